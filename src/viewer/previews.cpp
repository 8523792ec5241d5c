// PNG previews: report.html rendered by headless Chromium (software WebGL: SwiftShader).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "dhfcast/error.h"
#include "dhfcast/viewer.h"

extern char** environ;

namespace fs = std::filesystem;

namespace dhfcast {

namespace {

// A fresh Chromium profile, removed with this object (Chromium refuses to share one).
class TempProfile {
 public:
  TempProfile() {
    std::string pattern = (fs::temp_directory_path() / "dhfcast-chromium-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw Error(ErrorCode::Io, "cannot create " + pattern);
    path_ = pattern;
  }
  ~TempProfile() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempProfile(const TempProfile&) = delete;
  TempProfile& operator=(const TempProfile&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// Runs `args` (args[0] looked up on PATH) with its output discarded; its exit status, or -1 when
// it ran over `timeout_s` and was killed. Throws Error{Io} when it cannot be started.
int run_quietly(const std::vector<std::string>& args, double timeout_s) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  // Its own process group, so a timeout ends its helper processes too.
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attributes, 0);
  pid_t pid = 0;
  const int failed = posix_spawnp(&pid, argv[0], &actions, &attributes, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  if (failed)
    throw Error(ErrorCode::Io, args[0] + " cannot be run (" + std::strerror(failed) +
                                   "): the PNG previews need Chromium (Debian package chromium, "
                                   "installed by scripts/install-deps.sh)");
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(-pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Renders `page#view` into `png` (through a temporary file beside it).
void screenshot(const std::string& chromium, const fs::path& page, const std::string& view,
                const fs::path& png, double timeout_s) {
  const TempProfile profile;
  // Chromium picks the format by the extension: ".preview.dhfcast-tmp-PID.png". Appended to, not
  // concatenated: GCC 12 warns (-Wrestrict) about "." + name.
  std::string tmp_name = ".";
  tmp_name += png.stem().string();
  tmp_name += ".dhfcast-tmp-" + std::to_string(::getpid()) + png.extension().string();
  const fs::path tmp = png.parent_path() / tmp_name;
  std::vector<std::string> args = {
      chromium,
      "--headless",
      "--disable-gpu",
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
      "--disable-quic",
      "--no-first-run",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
      "--hide-scrollbars",
      "--user-data-dir=" + profile.path().string(),
      "--window-size=1200,800",
      "--virtual-time-budget=30000",
      "--screenshot=" + tmp.string(),
      "file://" + fs::absolute(page).lexically_normal().string() + "#" + view};
  // Chromium's sandbox cannot run as root.
  if (::geteuid() == 0) args.insert(args.begin() + 1, "--no-sandbox");
  const int status = run_quietly(args, timeout_s);
  std::error_code ec;
  if (status != 0 || !fs::is_regular_file(tmp, ec) || fs::file_size(tmp, ec) == 0) {
    fs::remove(tmp, ec);
    throw Error(ErrorCode::Io, status == -1
                                   ? chromium + " took over " + std::to_string(int(timeout_s)) +
                                         " s to render " + png.string()
                                   : chromium + " could not render " + png.string() +
                                         " (exit code " + std::to_string(status) + ")");
  }
  fs::rename(tmp, png, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw Error(ErrorCode::Io, "cannot write " + png.string() + ": " + ec.message());
  }
}

}  // namespace

void render_previews(const std::string& folder, const std::string& chromium, double timeout_s) {
  const fs::path page = fs::path(folder) / "report.html";
  std::error_code ec;
  if (!fs::is_regular_file(page, ec)) throw Error(ErrorCode::Io, "cannot read " + page.string());
  screenshot(chromium, page, "shot=parts", fs::path(folder) / "preview.png", timeout_s);
  screenshot(chromium, page, "shot=molds", fs::path(folder) / "molds.png", timeout_s);
}

}  // namespace dhfcast
