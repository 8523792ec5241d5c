#include "dhfcast/stop.h"

#include "dhfcast/error.h"

namespace dhfcast {

namespace {
std::atomic<bool> g_stop{false};
}  // namespace

void request_stop() noexcept { g_stop.store(true, std::memory_order_release); }

bool stop_requested() noexcept { return g_stop.load(std::memory_order_acquire); }

void throw_if_stop_requested() {
  if (stop_requested()) throw Error(ErrorCode::Stopped, "stopped on request");
}

std::atomic<bool>& stop_flag() noexcept { return g_stop; }

std::mutex& output_write_mutex() noexcept {
  static std::mutex m;
  return m;
}

}  // namespace dhfcast
