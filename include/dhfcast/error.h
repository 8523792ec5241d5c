// Errors: one exception type for failures; findings are returned as values.
#pragma once

#include <stdexcept>
#include <string>

namespace dhfcast {

// What went wrong, so the CLI can map it to an exit status.
enum class ErrorCode {
  InvalidInput,              // the input file is unreadable, malformed or not a valid solid
  InvalidOptions,            // an option is out of range
  Io,                        // a file could not be read or written
  TetrahedralizationFailed,  // the volume mesher gave no usable mesh
  BooleanFailed,             // a mesh boolean (molds) gave no valid solid
  Internal,                  // a broken invariant: a bug
  Stopped,                   // stopped on request before the end (request_stop(): --timeout)
};

// The only exception type dhfcast throws. what() is a one-line, user-facing message.
class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const noexcept { return code_; }

 private:
  ErrorCode code_;
};

// Checks one option: throws Error{InvalidOptions, "invalid option: " + what} unless ok; `what`
// names the option and its bounds.
inline void require_option(bool ok, const std::string& what) {
  if (!ok) throw Error(ErrorCode::InvalidOptions, "invalid option: " + what);
}

namespace detail {
[[noreturn]] void assert_fail(const char* cond, const std::string& msg, const char* file, int line);
}  // namespace detail

}  // namespace dhfcast

// Internal invariants only (never for user input). On when DHFCAST_ASSERTS; throws Error{Internal}.
#if DHFCAST_ASSERTS
#define DHF_ASSERT(cond, msg)                                                        \
  do {                                                                               \
    if (!(cond)) ::dhfcast::detail::assert_fail(#cond, (msg), __FILE__, __LINE__);   \
  } while (0)
#else
#define DHF_ASSERT(cond, msg) \
  do {                        \
  } while (0)
#endif
