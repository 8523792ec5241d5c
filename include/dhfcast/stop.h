// Stopping a run before it ends (the CLI's --timeout): a flag the long stages poll at safe
// points, and the writes of an output folder, which a stop never interrupts.
#pragma once

#include <atomic>
#include <mutex>

namespace dhfcast {

// Asks the running stages to stop at their next check point (any thread; async-signal-safe).
void request_stop() noexcept;
bool stop_requested() noexcept;
// Throws Error{Stopped} when a stop was requested. The stages call it where they may stop.
void throw_if_stop_requested();
// The flag itself, for CGAL Mesh_3's pointer_to_stop_atomic_boolean.
std::atomic<bool>& stop_flag() noexcept;

// Held while an output folder is built beside its place and swapped in (write_output(),
// rebuild_molds()): whoever ends the process without unwinding takes it first, so no half-built
// folder is left behind.
std::mutex& output_write_mutex() noexcept;

}  // namespace dhfcast
