// Runs the dhfcast executable as a user would: bad input gets a one-line error, a non-zero exit
// code and no output folder.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "dhfcast/mesh.h"
#include "support/test_support.h"

namespace fs = std::filesystem;
using namespace dhfcast;

namespace {

struct RunResult {
  int exit_code = -1;
  std::string err;
};

RunResult run(const std::string& args) {
  const std::string dir = test::temp_dir("cli");
  const std::string err_path = dir + "/stderr.txt";
  const std::string cmd = test::cli_path() + " " + args + " >/dev/null 2>" + err_path;
  const int status = std::system(cmd.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream f(err_path);
  std::stringstream ss;
  ss << f.rdbuf();
  r.err = ss.str();
  return r;
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

// An OBJ cube with 12 triangles; `drop` removes faces from the end, `extra` appends lines.
std::string cube_obj(int drop = 0, const std::string& extra = "") {
  std::string s =
      "v 0 0 0\nv 10 0 0\nv 10 10 0\nv 0 10 0\nv 0 0 10\nv 10 0 10\nv 10 10 10\nv 0 10 10\n";
  const char* faces[] = {"f 1 3 2", "f 1 4 3", "f 5 6 7", "f 5 7 8", "f 1 2 6", "f 1 6 5",
                         "f 2 3 7", "f 2 7 6", "f 3 4 8", "f 3 8 7", "f 4 1 5", "f 4 5 8"};
  for (int i = 0; i < 12 - drop; ++i) s += std::string(faces[i]) + "\n";
  return s + extra;
}

// Writes the cube to DIR/cube.obj and decomposes it into DIR/out with options fast enough for a
// test (2000 tets, 64 directions, 2 restarts), quiet, plus `extra`.
RunResult decompose_cube(const std::string& dir, const std::string& extra = "") {
  write_text(dir + "/cube.obj", cube_obj());
  return run("decompose " + dir + "/cube.obj -o " + dir +
             "/out --tets 2000 --directions 64 --restarts 2 --quiet" + extra);
}

class BadInput : public ::testing::TestWithParam<std::pair<std::string, std::string>> {};

TEST_P(BadInput, OneLineErrorNonZeroExitNoOutput) {
  const auto& [file_name, content] = GetParam();
  const std::string dir = test::temp_dir("bad");
  const std::string input = dir + "/" + file_name;
  write_text(input, content);
  const std::string out = dir + "/out";
  const RunResult r = run("decompose " + input + " -o " + out + " --tets 2000");
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_FALSE(fs::exists(out));
  // Exactly one line, naming the file.
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("error"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(file_name), std::string::npos) << r.err;
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    EXPECT_TRUE(e.path().filename() == file_name) << "left behind: " << e.path();
}

std::string truncated_binary_stl() {
  TriMesh box;
  box.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  box.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  const std::string dir = test::temp_dir("stl");
  write_stl(dir + "/t.stl", box);
  std::ifstream f(dir + "/t.stl", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  return bytes.substr(0, bytes.size() - 30);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BadInput,
    ::testing::Values(
        std::make_pair("open.obj", cube_obj(1)),
        std::make_pair("nonmanifold_edge.obj", cube_obj(0, "v 10 0 -10\nf 2 3 9\nf 3 2 9\n")),
        std::make_pair("self_intersecting.obj",
                       cube_obj() + "v 5 5 5\nv 15 5 5\nv 15 15 5\nv 5 15 5\nv 5 5 15\nv 15 5 15\n"
                                    "v 15 15 15\nv 5 15 15\n"
                                    "f 9 11 10\nf 9 12 11\nf 13 14 15\nf 13 15 16\nf 9 10 14\n"
                                    "f 9 14 13\nf 10 11 15\nf 10 15 14\nf 11 12 16\nf 11 16 15\n"
                                    "f 12 9 13\nf 12 13 16\n"),
        std::make_pair("truncated.stl", truncated_binary_stl()),
        std::make_pair("nan.obj",
                       "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 nan\n"
                       "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"),
        std::make_pair("empty.stl", std::string()),
        std::make_pair("garbage.off", "OFF\n3 1 0\n0 0 0\n1 zero 0\n")),
    [](const auto& info) { return fs::path(info.param.first).stem().string(); });

TEST(Cli, MissingFileIsAnIoError) {
  const std::string dir = test::temp_dir("missing");
  const RunResult r = run("decompose " + dir + "/nope.stl -o " + dir + "/out");
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/out"));
}

TEST(Cli, InputThatIsNoRegularFileIsAnIoError) {
  const std::string dir = test::temp_dir("not_a_file");
  const std::pair<std::string, std::string> cases[] = {{dir + "/nope", "no such file"},
                                                       {dir, "is a directory"},
                                                       {"/dev/null", "is not a regular file"}};
  for (const auto& [input, message] : cases) {
    const RunResult r = run("decompose " + input + " -o " + dir + "/out");
    EXPECT_EQ(r.exit_code, 4) << r.err;
    EXPECT_NE(r.err.find(input + ": " + message), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir + "/out"));
}

TEST(Cli, NegativeThreadsGetAReadableRange) {
  const std::string dir = test::temp_dir("threads");
  write_text(dir + "/cube.obj", cube_obj());
  const RunResult r = run("decompose " + dir + "/cube.obj -o " + dir + "/out --threads -1");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--threads: Value -1 not in range 0 to 1024"), std::string::npos) << r.err;
}

TEST(Cli, BadOptionIsAUsageError) {
  const std::string dir = test::temp_dir("opt");
  write_text(dir + "/cube.obj", cube_obj());
  const RunResult r = run("decompose " + dir + "/cube.obj -o " + dir + "/out --epsilon -1");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("epsilon"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/out"));
}

// --size scales the longest side to the given mm, whatever unit the file was in; it cannot be
// combined with --scale or --units, and `check --size` reads the input the same way.
TEST(Cli, SizeSetsTheLongestSide) {
  const std::string dir = test::temp_dir("size");
  write_text(dir + "/cube.obj", cube_obj());
  for (const char* other : {" --scale 2", " --units cm", " --size 0", " --size -1"}) {
    const RunResult r = run("decompose " + dir + "/cube.obj -o " + dir + "/bad --size 30" + other);
    EXPECT_EQ(r.exit_code, 2) << other << ": " << r.err;
    EXPECT_LT(r.err.size(), 200u) << r.err;
    EXPECT_FALSE(fs::exists(dir + "/bad"));
  }
  const RunResult r = run("decompose " + dir + "/cube.obj -o " + dir +
                          "/out --size 30 --tets 2000 --directions 64 --restarts 2 --no-molds -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const TriMesh part = load_solid(dir + "/out/parts/part_000.stl").mesh;
  EXPECT_NEAR(signed_volume(part), 27000.0, 270.0);
  EXPECT_EQ(run("check " + dir + "/out --input " + dir + "/cube.obj --size 30").exit_code, 0);
  EXPECT_EQ(run("check " + dir + "/out --input " + dir + "/cube.obj").exit_code, 3);
}

// The method and the carving need a positive undercut tolerance: zero is refused as a negative
// one is, before the input is even read (stderr holds the one error line and nothing else).
TEST(Cli, NonPositiveEpsilonIsRefusedUpFront) {
  for (const std::string eps : {"0", "-0.5"}) {
    const std::string dir = test::temp_dir("eps");
    write_text(dir + "/cube.obj", cube_obj());
    const RunResult r = run("decompose " + dir + "/cube.obj -o " + dir + "/out --epsilon " + eps);
    EXPECT_EQ(r.exit_code, 2) << eps << ": " << r.err;
    EXPECT_NE(r.err.find("--epsilon"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir + "/out"));
  }
}

TEST(Cli, ExistingOutputIsNotOverwrittenWithoutForce) {
  const std::string dir = test::temp_dir("exists");
  write_text(dir + "/cube.obj", cube_obj());
  fs::create_directories(dir + "/out");
  write_text(dir + "/out/keep.txt", "x");
  const RunResult r = run("decompose " + dir + "/cube.obj -o " + dir + "/out");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--force"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/out/keep.txt"));
}

TEST(Cli, OutputThatIsOrHoldsTheInputIsRefusedBeforeAnyWork) {
  const std::string dir = test::temp_dir("out_is_input");
  const std::string input = dir + "/in.obj";
  write_text(input, cube_obj());
  for (const std::string& out :
       {input, dir, dir + "/", dir + "/../" + fs::path(dir).filename().string()}) {
    const RunResult r = run("decompose " + input + " -o " + out + " --force --quiet");
    EXPECT_EQ(r.exit_code, 4) << out << ": " << r.err;
    EXPECT_NE(r.err.find("would replace the input"), std::string::npos) << r.err;
    ASSERT_TRUE(fs::is_regular_file(input));
  }
  // A file that is not the input is not replaced by a folder either.
  write_text(dir + "/notes.txt", "keep");
  const RunResult r = run("decompose " + input + " -o " + dir + "/notes.txt --force --quiet");
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_NE(r.err.find("exists and is not a folder"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_regular_file(dir + "/notes.txt"));
  // A parent folder nothing can be created in (even as root) is found before the work.
  const RunResult proc = run("decompose " + input + " -o /proc/dhfcast-out --quiet");
  EXPECT_EQ(proc.exit_code, 4) << proc.err;
  EXPECT_NE(proc.err.find("cannot write in /proc"), std::string::npos) << proc.err;
}

TEST(Cli, OutputWithTrailingSlashIsWrittenAndReplacedWholeLeavingNoTemporaryFolder) {
  const std::string dir = test::temp_dir("slash");
  write_text(dir + "/cube.obj", cube_obj());
  const std::string common = " --tets 2000 --directions 64 --restarts 2 --quiet --no-molds";
  RunResult r = run("decompose " + dir + "/cube.obj -o " + dir + "/out/" + common);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/out/parts/part_000.stl"));
  // Leftovers of a killed run: removed when their process is gone, kept while it runs.
  const pid_t dead = fork();
  if (dead == 0) _exit(0);
  waitpid(dead, nullptr, 0);
  fs::create_directories(dir + "/.out.dhfcast-tmp-" + std::to_string(dead) + "/parts");
  fs::create_directories(dir + "/.out.dhfcast-tmp-1");
  write_text(dir + "/out/stale.txt", "old");
  r = run("decompose " + dir + "/cube.obj -o " + dir + "/out/ --force" + common);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/out/parts/part_000.stl"));
  EXPECT_FALSE(fs::exists(dir + "/out/stale.txt"));
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{".out.dhfcast-tmp-1", "cube.obj", "out"}));
}

// Runs the CLI with `args` (stdout and stderr discarded) and SIGKILLs it after `after` unless it
// ended before; returns its wall time.
double run_killed_after(const std::vector<std::string>& args, std::chrono::duration<double> after) {
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<char*> argv;
    const std::string cli = test::cli_path();
    argv.push_back(const_cast<char*>(cli.c_str()));
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    freopen("/dev/null", "w", stdout);
    freopen("/dev/null", "w", stderr);
    execv(cli.c_str(), argv.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() - start >= after) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The folder `out` is one whole decomposition: its JSON parses, and every file it names is a
// complete binary STL. Returns the JSON.
nlohmann::json expect_whole(const std::string& out) {
  nlohmann::json j;
  std::ifstream in(out + "/decomposition.json");
  EXPECT_TRUE(in.good()) << out << " has no decomposition.json";
  if (!in) return j;
  j = nlohmann::json::parse(in, nullptr, false);
  EXPECT_FALSE(j.is_discarded()) << out << "/decomposition.json is not whole";
  if (j.is_discarded()) return j;
  std::vector<std::string> files;
  for (const auto& p : j["parts"]) {
    files.push_back(p["mesh"]);
    if (p.contains("molds") && p["molds"].contains("up"))
      for (const char* half : {"up", "down"}) files.push_back(p["molds"][half]);
  }
  for (const std::string& f : files) {
    std::ifstream stl(out + "/" + f, std::ios::binary);
    char header[84] = {};
    stl.read(header, 84);
    std::uint32_t n = 0;
    std::memcpy(&n, header + 80, 4);
    std::error_code ec;
    EXPECT_EQ(fs::file_size(out + "/" + f, ec), 84u + 50u * n) << f << " is not whole";
  }
  return j;
}

// decompose --force and molds, killed at random instants, leave either the whole old folder or
// the whole new one, never a mix or nothing; leftovers of the killed runs go with the next run.
TEST(Cli, KilledAtAnyInstantLeavesTheOldFolderOrTheNewOneWhole) {
  const std::string dir = test::temp_dir("kill");
  write_text(dir + "/cube.obj", cube_obj());
  const std::string out = dir + "/out";
  const std::vector<std::string> common = {"--tets",     "2000", "--directions", "64",
                                           "--restarts", "2",    "--no-molds",   "--force"};
  auto decompose = [&](int seed) {
    std::vector<std::string> args = {"decompose", dir + "/cube.obj", "-o",
                                     out,         "--seed",          std::to_string(seed)};
    args.insert(args.end(), common.begin(), common.end());
    return args;
  };
  const double full = run_killed_after(decompose(1), std::chrono::seconds(120));
  ASSERT_EQ(expect_whole(out)["parameters"]["seed"], 1);
  std::mt19937 random(7);
  std::uniform_real_distribution<double> instant(0.2, 1.2);  // mostly late: the swap is last
  for (int i = 0; i < 30; ++i) {
    const int seed = 2 + i % 2;
    run_killed_after(decompose(seed), std::chrono::duration<double>(instant(random) * full));
    const nlohmann::json j = expect_whole(out);
    ASSERT_FALSE(j.is_discarded()) << "run " << i;
    EXPECT_TRUE(j["parameters"]["seed"] == 1 || j["parameters"]["seed"] == 2 ||
                j["parameters"]["seed"] == 3)
        << "run " << i;
  }
  // Molds: the old folder has none, the new one a mold per part.
  const double molds = run_killed_after({"molds", out}, std::chrono::seconds(300));
  ASSERT_TRUE(expect_whole(out)["parts"][0].contains("molds"));
  for (int i = 0; i < 20; ++i) {
    const std::string wall = i % 2 ? "4" : "6";
    run_killed_after({"molds", out, "--wall", wall},
                     std::chrono::duration<double>(instant(random) * molds));
    const nlohmann::json j = expect_whole(out);
    ASSERT_FALSE(j.is_discarded()) << "run " << i;
    const double w = j["parameters"]["molds"]["wall_mm"];
    EXPECT_TRUE(w == 5 || w == 4 || w == 6) << "run " << i << ": wall " << w;
  }
  // A last run in peace removes every leftover.
  ASSERT_LT(run_killed_after(decompose(1), std::chrono::seconds(120)), 120);
  expect_whole(out);
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    EXPECT_TRUE(e.path().filename() == "cube.obj" || e.path().filename() == "out") << e.path();
}

// --timeout stops decompose (in the volume mesher, here), molds and check cleanly: exit code 6,
// one line, no folder written or changed, no temporary folder left.
TEST(Cli, TimeoutStopsWithExitCode6AndWritesNothing) {
  const std::string knot = test::cgal_mesh("knot1.off");
  if (knot.empty()) GTEST_SKIP() << "CGAL's data set is absent";
  const std::string dir = test::temp_dir("timeout");
  const std::string out = dir + "/out";
  const auto t0 = std::chrono::steady_clock::now();
  const RunResult r = run("decompose " + knot + " --size 50 -o " + out + " --timeout 1");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.exit_code, 6) << r.err;
  // After the progress lines, one error line.
  const std::string last_line =
      "dhfcast: error: time limit of 1 s reached (--timeout); nothing "
      "written\n";
  EXPECT_TRUE(r.err.ends_with(last_line)) << r.err;
  EXPECT_EQ(r.err.find("error"), r.err.size() - last_line.size() + 9) << r.err;
  EXPECT_LT(seconds, 15);  // the deadline, the watchdog's grace and some
  EXPECT_TRUE(fs::is_empty(dir)) << "left " << fs::directory_iterator(dir)->path();

  // molds and check on a folder: stopped before they are done, the folder unchanged.
  write_text(dir + "/cube.obj", cube_obj());
  ASSERT_EQ(run("decompose " + dir + "/cube.obj -o " + out + " --tets 2000 --quiet").exit_code, 0);
  const std::string json_before = [&] {
    std::stringstream s;
    s << std::ifstream(out + "/decomposition.json").rdbuf();
    return s.str();
  }();
  for (const std::string& command : {"molds " + out + " --wall 7", "check " + out}) {
    const RunResult stopped = run("--timeout 0.001 " + command);
    EXPECT_EQ(stopped.exit_code, 6) << command << ": " << stopped.err;
    EXPECT_NE(stopped.err.find("time limit of 0.001 s reached"), std::string::npos) << stopped.err;
    std::stringstream after;
    after << std::ifstream(out + "/decomposition.json").rdbuf();
    EXPECT_EQ(after.str(), json_before) << command;
    for (const fs::directory_entry& e : fs::directory_iterator(dir))
      EXPECT_TRUE(e.path().filename() == "cube.obj" || e.path().filename() == "out") << e.path();
  }
  EXPECT_EQ(run("check " + out + " --timeout 600").exit_code, 0);
  EXPECT_EQ(run("check " + out + " --timeout -1").exit_code, 2);
}

TEST(Cli, CubeGivesOnePartAndTheContract) {
  const std::string dir = test::temp_dir("cube");
  const RunResult r = decompose_cube(dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/out/decomposition.json"));
  EXPECT_TRUE(fs::exists(dir + "/out/parts/part_000.stl"));
  EXPECT_FALSE(fs::exists(dir + "/out/parts/part_001.stl"));
  const TriMesh part = load_solid(dir + "/out/parts/part_000.stl").mesh;
  EXPECT_NEAR(signed_volume(part), 1000.0, 10.0);
  // A cube is accessible everywhere along any axis: its one part holds no tet its direction
  // does not reach.
  std::stringstream json;
  json << std::ifstream(dir + "/out/decomposition.json").rdbuf();
  EXPECT_NE(json.str().find("\"inaccessible_tets\": 0,"), std::string::npos) << json.str();
  // Molds are built by default, and the checker accepts them.
  EXPECT_TRUE(fs::exists(dir + "/out/molds/part_000_up.stl"));
  EXPECT_TRUE(fs::exists(dir + "/out/molds/part_000_down.stl"));
  EXPECT_EQ(run("check " + dir + "/out").exit_code, 0);
}

TEST(Cli, NoMoldsSkipsThemAndMoldsBuildsThemLater) {
  const std::string dir = test::temp_dir("cube_molds");
  RunResult r = decompose_cube(dir, " --no-molds");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/out/molds"));
  std::stringstream before;
  before << std::ifstream(dir + "/out/decomposition.json").rdbuf();
  EXPECT_EQ(before.str().find("\"molds\""), std::string::npos);

  r = run("molds " + dir + "/out --wall 8 --sprue-diameter 5 --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/out/molds/part_000_up.stl"));
  std::stringstream after;
  after << std::ifstream(dir + "/out/decomposition.json").rdbuf();
  EXPECT_NE(after.str().find("\"wall_mm\": 8.0"), std::string::npos) << after.str();
  EXPECT_NE(after.str().find("\"sprues\""), std::string::npos);
  EXPECT_EQ(run("check " + dir + "/out").exit_code, 0);
  // A thicker wall gives a larger block.
  const Box3 thick = bounding_box(read_mesh(dir + "/out/molds/part_000_up.stl").vertices);
  ASSERT_EQ(run("molds " + dir + "/out --wall 4 --quiet").exit_code, 0);
  const Box3 thin = bounding_box(read_mesh(dir + "/out/molds/part_000_up.stl").vertices);
  EXPECT_GT(thick.diagonal(), thin.diagonal() + 10.0);

  r = run("molds " + dir + "/out --wall 2 --sprue-diameter 6");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--sprue-diameter"), std::string::npos) << r.err;
  EXPECT_EQ(run("molds " + dir + "/nowhere --quiet").exit_code, 4);
}

std::string read_text(const std::string& path) {
  std::stringstream text;
  text << std::ifstream(path, std::ios::binary).rdbuf();
  return text.str();
}

TEST(Cli, MoldsRefusesABadFolderBeforeAnyWorkAndLeavesItUntouched) {
  const std::string dir = test::temp_dir("molds_bad");
  write_text(dir + "/open.obj", cube_obj(1));
  ASSERT_EQ(decompose_cube(dir, " --no-molds").exit_code, 0);
  const std::string json_path = dir + "/out/decomposition.json";
  const std::string good = read_text(json_path);
  fs::create_directory_symlink(dir + "/out/parts", dir + "/out/linked");
  fs::copy_file(dir + "/open.obj", dir + "/out/parts/open.obj");
  // Each edit of decomposition.json, and what the error names.
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    return text.replace(text.find(from), from.size(), to);
  };
  const std::string mesh = "\"mesh\": \"parts/part_000.stl\"";
  const std::pair<std::string, std::string> cases[] = {
      {replaced(mesh, "\"mesh\": \"parts/open.obj\""),
       "parts[0] mesh parts/open.obj is not a solid: not closed"},
      {replaced("\"direction\": [", "\"direction\": [1e308, 1e308, 0], \"was\": ["),
       "parts[0].direction is not a number within +-1e+06"},
      {replaced(mesh, "\"mesh\": \"" + dir + "/out/parts/part_000.stl\""),
       "is not relative to the folder"},
      {replaced(mesh, "\"mesh\": \"parts/../parts/part_000.stl\""), "has a '..' component"},
      {replaced(mesh, "\"mesh\": \"linked/part_000.stl\""), "goes through the symlink linked"},
      {replaced("\"parameters\": {", "\"parameters\": 1, \"was\": {"),
       "parameters is not an object"},
      {replaced("\"epsilon_mm\": 0.4", "\"epsilon_mm\": \"0.4\""),
       "parameters.epsilon_mm is not a number"},
      {replaced("\"epsilon_mm\": 0.4", "\"epsilon_mm\": 1e400"),
       "not valid JSON at parameters.epsilon_mm: number overflow parsing '1e400'"},
      {replaced("\"format\"", "\"deep\": " + std::string(100000, '[') + std::string(100000, ']') +
                                  ", \"format\""),
       "deeper than 64 levels"}};
  for (const auto& [text, message] : cases) {
    write_text(json_path, text);
    const RunResult r = run("molds " + dir + "/out --quiet");
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
    EXPECT_EQ(read_text(json_path), text);
    EXPECT_FALSE(fs::exists(dir + "/out/molds"));
  }
  // A good folder is swapped whole: the part file is the same file, linked, and no temporary
  // folder is left beside it.
  write_text(json_path, good);
  struct stat before {
  }, after{};
  ::stat((dir + "/out/parts/part_000.stl").c_str(), &before);
  ASSERT_EQ(run("molds " + dir + "/out --quiet").exit_code, 0);
  ::stat((dir + "/out/parts/part_000.stl").c_str(), &after);
  EXPECT_EQ(before.st_ino, after.st_ino);
  EXPECT_TRUE(fs::exists(dir + "/out/molds/part_000_up.stl"));
  EXPECT_TRUE(fs::is_symlink(dir + "/out/linked"));
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".dhfcast-tmp-"), std::string::npos) << e.path();
}

// decompose writes report.html with the folder; `report` writes the same bytes again, and refuses
// a bad folder with a one-line error, writing nothing.
TEST(Cli, ReportIsWrittenWithTheFolderAndRefusesABadOne) {
  const std::string dir = test::temp_dir("report");
  RunResult r = decompose_cube(dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string page = dir + "/out/report.html";
  const std::string html = read_text(page);
  ASSERT_NE(html.find("\"parts\":[{\"id\":0"), std::string::npos);
  EXPECT_NE(html.find("OrbitControls"), std::string::npos);  // three.js is inlined
  EXPECT_EQ(html.find("<script src"), std::string::npos);    // and nothing is fetched
  fs::remove(page);
  r = run("report " + dir + "/out");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_text(page), html);

  // check --html puts the verdicts in, and so does a check.json in the folder; molds rebuilds the
  // page with the new molds, and drops the verdicts on the old ones.
  r = run("check " + dir + "/out --html");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(read_text(page).find("\"checks\":{\"passed\":true"), std::string::npos);
  write_text(dir + "/out/check.json", R"({"passed": false, "checks": [{"name": "dhf",
      "status": "fail", "summary": "part 0 is not", "figures": {}, "at": [1, 2, 3]}]})");
  ASSERT_EQ(run("report " + dir + "/out").exit_code, 0);
  EXPECT_NE(
      read_text(page).find("\"status\":\"fail\",\"summary\":\"part 0 is not\",\"at\":[1,2,3]"),
      std::string::npos);
  ASSERT_EQ(run("molds " + dir + "/out --wall 7 --quiet").exit_code, 0);
  EXPECT_NE(read_text(page), html);
  EXPECT_EQ(read_text(page).find("\"checks\":{"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir + "/out/check.json"));

  const std::string json_path = dir + "/out/decomposition.json";
  const std::string good = read_text(json_path);
  fs::remove(page);
  auto refused = [&](const std::string& why) {
    const RunResult bad = run("report " + dir + "/out");
    EXPECT_EQ(bad.exit_code, 3) << why << ": " << bad.err;
    EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << why << ": " << bad.err;
    EXPECT_FALSE(fs::exists(page)) << why;
    for (const fs::directory_entry& e : fs::directory_iterator(dir + "/out"))
      EXPECT_EQ(e.path().filename().string().find(".dhfcast-tmp-"), std::string::npos) << e.path();
    return bad.err;
  };
  write_text(json_path, good.substr(0, good.size() / 2));
  EXPECT_NE(refused("corrupt JSON").find("not valid JSON"), std::string::npos);
  write_text(json_path, good);
  fs::rename(dir + "/out/parts/part_000.stl", dir + "/out/part.stl");
  EXPECT_NE(refused("missing part").find("parts/part_000.stl does not exist"), std::string::npos);
  write_text(dir + "/out/parts/part_000.stl", "solid broken\nfacet normal 0 0 1\n");
  EXPECT_NE(refused("corrupt part").find("parts/part_000.stl"), std::string::npos);
  EXPECT_EQ(run("report " + dir + "/nowhere").exit_code, 4);
}

TEST(Cli, PartsAreCutFromTheInputUnlessTetSurfaceIsAsked) {
  const std::string path = test::cgal_mesh("ellipsoid.off");
  if (path.empty()) GTEST_SKIP() << "CGAL data set absent (install libcgal-demo)";
  const std::string dir = test::temp_dir("ellipsoid");
  const std::string common =
      " --scale 50 --tets 3000 --directions 64 --restarts 2 --quiet --no-molds";
  ASSERT_EQ(run("decompose " + path + " -o " + dir + "/exact" + common).exit_code, 0);
  ASSERT_EQ(run("decompose " + path + " -o " + dir + "/tets" + common + " --tet-surface").exit_code,
            0);
  TriMesh input = read_mesh(path);
  for (Vec3& v : input.vertices) v *= 50.0;
  const double volume = signed_volume(input);
  auto parts_volume = [&](const std::string& out) {
    double sum = 0.0;
    for (const auto& f : fs::directory_iterator(dir + "/" + out + "/parts"))
      sum += signed_volume(read_mesh(f.path().string()));
    return sum;
  };
  // Float STL coordinates: the exact parts match the input to rounding, the tet boundary not.
  EXPECT_NEAR(parts_volume("exact"), volume, 1e-6 * volume);
  EXPECT_GT(std::abs(parts_volume("tets") - volume), 1e-4 * volume);
  std::stringstream json;
  json << std::ifstream(dir + "/tets/decomposition.json").rdbuf();
  EXPECT_NE(json.str().find("\"exact_outer_surface\": false"), std::string::npos);
  EXPECT_EQ(json.str().find("\"outer_surface_cut\""), std::string::npos);

  // check scales --input as decompose did; unscaled, the volumes disagree and it says so.
  const RunResult unscaled = run("check " + dir + "/exact --input " + path);
  EXPECT_EQ(unscaled.exit_code, 3);
  EXPECT_NE(unscaled.err.find("--scale"), std::string::npos) << unscaled.err;
  const std::string report = dir + "/check.txt";
  std::system(
      (test::cli_path() + " check " + dir + "/exact --input " + path + " --scale 50 > " + report)
          .c_str());
  std::stringstream text;
  text << std::ifstream(report).rdbuf();
  EXPECT_NE(text.str().find("PASS coverage"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("PASS fidelity"), std::string::npos) << text.str();
}

// CGAL's hand.off at 150 times its size, default options: decompose crashed (SIGSEGV in a
// corefinement right after segmentation). It must finish, and check must give a verdict.
TEST(CliExtended, HandAtScale150DecomposesAndCheckGivesAVerdict) {
  const std::string hand = test::cgal_mesh("hand.off");
  if (hand.empty()) GTEST_SKIP() << "CGAL's data set is absent";
  const std::string out = test::temp_dir("hand") + "/out";
  const RunResult r = run("decompose " + hand + " --scale 150 -o " + out + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const RunResult c = run("check " + out + " --input " + hand + " --scale 150");
  EXPECT_TRUE(c.exit_code == 0 || c.exit_code == 5) << c.exit_code << ": " << c.err;
  EXPECT_TRUE(c.err.empty()) << c.err;
}

}  // namespace
