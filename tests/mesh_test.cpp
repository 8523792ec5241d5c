// Tests of mesh input, validation and output: every reader on small files written here, real
// meshes, and one invalid input per kind of problem.
#include "dhfcast/mesh.h"

#include <gtest/gtest.h>

#include <bit>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "dhfcast/error.h"
#include "support/test_support.h"

namespace dhfcast {
namespace {

// The unit cube's corners: vertex i is (i & 1, (i >> 1) & 1, (i >> 2) & 1) scaled by kBoxSize.
const Vec3 kBoxSize(10.0, 20.0, 30.0);
constexpr double kBoxVolume = 6000.0;
// Its faces as outward quads (counter-clockwise seen from outside), 0-based.
constexpr int kBoxQuads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                 {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};

Vec3 box_corner(int i) {
  return Vec3((i & 1) * kBoxSize.x(), ((i >> 1) & 1) * kBoxSize.y(), ((i >> 2) & 1) * kBoxSize.z());
}

std::string write_file(const std::string& name, const std::string& content) {
  static const std::string dir = test::temp_dir("mesh");
  const std::string path = dir + "/" + name;
  std::ofstream(path, std::ios::binary) << content;
  return path;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string ascii_stl(const TriMesh& mesh) {
  std::ostringstream out;
  out.precision(17);
  out << "solid test\n";
  for (const Tri& t : mesh.triangles) {
    out << "  facet normal 0 0 0\n    outer loop\n";
    for (std::int32_t v : t)
      out << "      vertex " << mesh.vertices[v].x() << ' ' << mesh.vertices[v].y() << ' '
          << mesh.vertices[v].z() << '\n';
    out << "    endloop\n  endfacet\n";
  }
  out << "endsolid test\n";
  return out.str();
}

// Little- or big-endian bytes of a scalar.
template <class T>
std::string bytes_of(T value, bool little) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (little != (std::endian::native == std::endian::little))
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  return std::string(b, sizeof(T));
}

// The box as a binary PLY: float x y z plus an extra uchar property, an extra element before the
// faces, and quads listed as "vertex_index" with uchar counts and uint indices.
std::string binary_ply_box(bool little) {
  std::string out = std::string("ply\nformat ") +
                    (little ? "binary_little_endian" : "binary_big_endian") +
                    " 1.0\ncomment written by the test\n"
                    "element vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
                    "property uchar quality\n"
                    "element material 1\nproperty list uchar float coefficients\n"
                    "element face 6\nproperty list uchar uint vertex_index\nend_header\n";
  for (int i = 0; i < 8; ++i) {
    for (int k = 0; k < 3; ++k) out += bytes_of(static_cast<float>(box_corner(i)[k]), little);
    out += bytes_of(std::uint8_t{7}, little);
  }
  out += bytes_of(std::uint8_t{2}, little) + bytes_of(0.5f, little) + bytes_of(0.25f, little);
  for (const auto& q : kBoxQuads) {
    out += bytes_of(std::uint8_t{4}, little);
    for (int v : q) out += bytes_of(static_cast<std::uint32_t>(v), little);
  }
  return out;
}

void expect_welded_box(const TriMesh& mesh) {
  EXPECT_EQ(mesh.vertices.size(), 8u);
  EXPECT_EQ(mesh.triangles.size(), 12u);
  EXPECT_DOUBLE_EQ(signed_volume(mesh), kBoxVolume);
  const MeshDiagnostics d = validate_mesh(mesh);
  EXPECT_TRUE(d.ok()) << d.first_problem;
  EXPECT_DOUBLE_EQ(d.volume_mm3, kBoxVolume);
}

TriMesh box() { return test::make_box(Vec3::Zero(), kBoxSize); }

// Runs load_solid() and returns the message of the Error{code} it must throw.
std::string load_error(const std::string& path, ErrorCode code = ErrorCode::InvalidInput,
                       const LoadOptions& opts = {}) {
  try {
    load_solid(path, opts);
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "load_solid(" << path << ") did not throw";
  return "";
}

// load_solid() must fail with "PATH: <problem...>" where the problem starts with `prefix`.
void expect_invalid(const std::string& path, const std::string& prefix) {
  const std::string message = load_error(path);
  EXPECT_EQ(message.rfind(path + ": " + prefix, 0), 0u) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

// --- writing and reading every format ---

TEST(WriteStl, RoundTripGivesTheWeldedBoxAndUnitNormals) {
  const std::string path = write_file("box.stl", "");
  write_stl(path, box());
  const std::string bytes = read_bytes(path);
  ASSERT_EQ(bytes.size(), 84u + 50u * 12u);
  EXPECT_EQ(bytes.substr(0, 18), "dhfcast binary STL");
  for (int t = 0; t < 12; ++t) {
    float n[3];
    std::memcpy(n, bytes.data() + 84 + 50 * t, sizeof n);
    EXPECT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6);
  }
  const TriMesh back = read_mesh(path);
  expect_welded_box(back);
  // Float32 keeps these coordinates exactly.
  EXPECT_EQ(bounding_box(back.vertices).max, kBoxSize);
}

TEST(WriteStl, UnwritablePathIsAnIoError) {
  try {
    write_stl("/nonexistent-dir/x.stl", box());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Io);
    EXPECT_NE(std::string(e.what()).find("cannot write /nonexistent-dir/x.stl: "),
              std::string::npos);
  }
}

TEST(ReadMesh, AsciiStl) {
  const TriMesh mesh = read_mesh(write_file("ascii.stl", ascii_stl(box())));
  expect_welded_box(mesh);
}

TEST(ReadMesh, BinaryStlWhoseHeaderStartsWithSolid) {
  const std::string path = write_file("solid_header.stl", "");
  write_stl(path, box());
  std::string bytes = read_bytes(path);
  bytes.replace(0, 18, "solid binary mesh ");
  const TriMesh mesh = read_mesh(write_file("solid_header.STL", bytes));
  expect_welded_box(mesh);
}

TEST(ReadMesh, ObjWithQuadsNegativeIndicesAndAllFaceForms) {
  std::ostringstream obj;
  obj << "# box\nmtllib none.mtl\no box\n";
  for (int i = 0; i < 8; ++i)
    obj << "v " << box_corner(i).x() << ' ' << box_corner(i).y() << ' ' << box_corner(i).z()
        << "\n";
  obj << "vt 0 0\nvn 0 0 1\ng sides\nusemtl none\n";
  const char* forms[] = {"%", "%/1", "%/1/1", "%//1"};
  for (int f = 0; f < 6; ++f) {
    obj << "f";
    for (int k = 0; k < 4; ++k) {
      // Alternate positive (1-based) and negative (from the end) indices.
      const int index = (f + k) % 2 ? kBoxQuads[f][k] + 1 : kBoxQuads[f][k] - 8;
      std::string token = forms[(f + k) % 4];
      token.replace(0, 1, std::to_string(index));
      obj << ' ' << token;
    }
    obj << "\n";
  }
  expect_welded_box(read_mesh(write_file("box.obj", obj.str())));
}

TEST(ReadMesh, AsciiPlyWithExtraPropertiesAndElements) {
  std::ostringstream ply;
  ply << "ply\r\nformat ascii 1.0\r\ncomment test\r\nelement vertex 8\r\n"
         "property double x\r\nproperty double y\r\nproperty double z\r\n"
         "property uchar red\r\nproperty list uchar int extra\r\n"
         "element face 6\r\nproperty uchar flags\r\nproperty list uchar int vertex_indices\r\n"
         "element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n";
  for (int i = 0; i < 8; ++i)
    ply << box_corner(i).x() << ' ' << box_corner(i).y() << ' ' << box_corner(i).z()
        << " 255 2 -1 -2\r\n";
  for (const auto& q : kBoxQuads)
    ply << "0 4 " << q[0] << ' ' << q[1] << ' ' << q[2] << ' ' << q[3] << "\r\n";
  ply << "0 1\r\n";
  expect_welded_box(read_mesh(write_file("box.ply", ply.str())));
}

TEST(ReadMesh, BinaryPlyBothByteOrders) {
  expect_welded_box(read_mesh(write_file("box_le.ply", binary_ply_box(true))));
  expect_welded_box(read_mesh(write_file("box_be.PLY", binary_ply_box(false))));
}

// Found by fuzzing: an element of 66666666666 items without properties looped for minutes. It
// has nothing to read; an element with properties announcing more items than bytes is refused.
TEST(ReadMesh, PlyElementCountsBeyondTheFileAreNotLoopedOver) {
  std::string empty = binary_ply_box(true);
  empty.insert(empty.find("end_header"), "element nothing 66666666666\n");
  expect_welded_box(read_mesh(write_file("nothing.ply", empty)));
  std::string huge = binary_ply_box(true);
  huge.insert(huge.find("end_header"), "element extra 66666666666\nproperty uchar a\n");
  expect_invalid(write_file("huge.ply", huge),
                 "the header announces 66666666666 'extra' elements but the file has only ");
}

TEST(ReadMesh, OffWithQuadsCommentsAndColours) {
  std::ostringstream off;
  off << "OFF\n# a box\n\n8 6 12\n";
  for (int i = 0; i < 8; ++i)
    off << box_corner(i).x() << ' ' << box_corner(i).y() << ' ' << box_corner(i).z() << "  # v\n";
  for (const auto& q : kBoxQuads)
    off << "4 " << q[0] << ' ' << q[1] << ' ' << q[2] << ' ' << q[3] << " 255 0 0\n";
  expect_welded_box(read_mesh(write_file("box.off", off.str())));
}

TEST(ReadMesh, WeldsOnlyIdenticalCoordinatesAndDropsUnusedVertices) {
  // Two triangles sharing an edge, one copy nudged by one ulp, plus an unused vertex.
  const double nudged = std::nextafter(1.0, 2.0);
  std::ostringstream obj;
  obj.precision(17);
  obj << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nv " << nudged << " 0 0\nv -0 1 0\nv 1 1 0\n"
      << "f 1 2 3\nf 5 7 6\n";
  const TriMesh mesh = read_mesh(write_file("weld.obj", obj.str()));
  EXPECT_EQ(mesh.vertices.size(), 5u);  // -0 welds with 0; the nudged vertex stays separate
  EXPECT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangles[1][2], mesh.triangles[0][2]);
  EXPECT_NE(mesh.triangles[1][0], mesh.triangles[0][1]);
}

// --- real meshes ---

TEST(ReadMesh, CgalMeshesAreValidSolids) {
  for (const char* name : {"elephant.off", "fandisk.off", "bunny00.off", "cube.off"}) {
    SCOPED_TRACE(name);
    const std::string path = test::cgal_mesh(name);
    if (path.empty()) GTEST_SKIP() << "CGAL's data set is absent";
    const TriMesh mesh = read_mesh(path);
    const MeshDiagnostics d = validate_mesh(mesh);
    EXPECT_TRUE(d.ok()) << d.first_problem;
    EXPECT_NE(d.volume_mm3, 0.0);
    // Scaled to ~100 mm, it loads outward.
    const TriMesh scaled = test::load_scaled(path, 100.0);
    EXPECT_GT(signed_volume(scaled), 0.0);
    EXPECT_NEAR(bounding_box(scaled.vertices).diagonal(), 100.0, 1e-9);
  }
}

TEST(ReadMesh, SharedModelsAreValidSolidsAndLoadFast) {
  const char* names[] = {"bunny.stl",   "armadillo.stl", "elephant.stl",    "fertility.stl",
                         "duck.stl",    "bimba.stl",     "doubletorus.stl", "dragonstand.stl",
                         "fandisk.stl", "rockerarm.stl", "pinion.stl",      "mastercylinder.stl",
                         "joint.stl",   "wrench.stl",    "teacup.stl",      "vase.stl"};
  if (test::extra_model("bunny.stl").empty()) GTEST_SKIP() << "extended models are absent";
  for (const char* name : names) {
    SCOPED_TRACE(name);
    const std::string path = test::extra_model(name);
    if (path.empty()) continue;
    const auto t0 = std::chrono::steady_clock::now();
    const TriMesh mesh = read_mesh(path);
    const auto t1 = std::chrono::steady_clock::now();
    const MeshDiagnostics d = validate_mesh(mesh);
    const auto t2 = std::chrono::steady_clock::now();
    EXPECT_TRUE(d.ok()) << d.first_problem;
    EXPECT_GT(d.volume_mm3, 0.0);
    // A closed genus-g surface: V - E + F = 2 - 2g, with E = 3F/2, so F = 2V - 4 + 4g.
    const auto num_triangles = static_cast<std::int64_t>(mesh.triangles.size());
    const auto num_vertices = static_cast<std::int64_t>(mesh.vertices.size());
    EXPECT_EQ((num_triangles - 2 * num_vertices + 4) % 4, 0);
    // The binary STL's normal-free float32 vertices come back exactly through write_stl().
    const std::string copy = write_file(std::string("copy_") + name, "");
    write_stl(copy, mesh);
    const TriMesh again = read_mesh(copy);
    EXPECT_EQ(again.vertices, mesh.vertices);
    EXPECT_EQ(again.triangles, mesh.triangles);
    std::printf("  %-20s %6zu triangles  read %.3f s  validate %.3f s\n", name,
                mesh.triangles.size(), std::chrono::duration<double>(t1 - t0).count(),
                std::chrono::duration<double>(t2 - t1).count());
  }
}

// --- invalid inputs: each gives its own first problem, and an Error naming the file ---

TEST(LoadSolid, OpenBoxIsNotClosed) {
  TriMesh open = box();
  open.triangles.pop_back();
  const MeshDiagnostics d = validate_mesh(open);
  EXPECT_EQ(d.boundary_edges, 3);
  EXPECT_EQ(d.first_problem.rfind("not closed: 3 boundary edges, e.g. edge (v", 0), 0u)
      << d.first_problem;
  EXPECT_NE(d.first_problem.find("is used by only one triangle (triangle "), std::string::npos);
  const std::string path = write_file("open.stl", "");
  write_stl(path, open);
  expect_invalid(path, "not closed: 3 boundary edges");
}

TEST(LoadSolid, CgalMeshWithHolesIsNotClosed) {
  const std::string path = test::cgal_mesh("mech-holes-shark.off");
  if (path.empty()) GTEST_SKIP() << "CGAL's data set is absent";
  EXPECT_GT(validate_mesh(read_mesh(path)).boundary_edges, 0);
  expect_invalid(path, "not closed: ");
}

TEST(LoadSolid, BoxesSharingAnEdgeAreNotManifold) {
  TriMesh mesh = box();
  const TriMesh other =
      test::make_box(kBoxSize.cwiseProduct(Vec3(1, 1, 0)), kBoxSize.cwiseProduct(Vec3(2, 2, 1)));
  const auto offset = static_cast<std::int32_t>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (Tri t : other.triangles)
    mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  const std::string path = write_file("edge_touch.stl", "");
  write_stl(path, mesh);  // read_mesh() welds the shared edge
  const MeshDiagnostics d = validate_mesh(read_mesh(path));
  EXPECT_EQ(d.nonmanifold_edges, 1);
  EXPECT_EQ(d.boundary_edges, 0);
  expect_invalid(path, "not 2-manifold: 1 edge is shared by more than two triangles, e.g. edge (v");
}

TEST(LoadSolid, TetsTouchingAtAVertexAreNotManifold) {
  // Two tets sharing vertex 0, on opposite sides of it.
  std::ostringstream off;
  off << "OFF\n7 8 0\n0 0 0\n10 0 0\n0 10 0\n0 0 10\n-10 0 0\n0 -10 0\n0 0 -10\n"
      << "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"   // tet (0, 1, 2, 3), outward
      << "3 0 4 5\n3 0 6 4\n3 0 5 6\n3 4 6 5\n";  // tet (0, 4, 5, 6), outward
  const std::string path = write_file("vertex_touch.off", off.str());
  const TriMesh mesh = read_mesh(path);
  const MeshDiagnostics d = validate_mesh(mesh);
  EXPECT_EQ(d.nonmanifold_vertices, 1);
  EXPECT_EQ(d.nonmanifold_edges, 0);
  EXPECT_EQ(d.boundary_edges, 0);
  EXPECT_EQ(d.misoriented_edges, 0);
  EXPECT_GT(d.volume_mm3, 0.0);
  expect_invalid(path, "not 2-manifold at vertex 0 (0, 0, 0): its triangles form 2 separate fans");
}

TEST(LoadSolid, OneFlippedTriangleIsInconsistentlyOriented) {
  TriMesh mesh = box();
  std::swap(mesh.triangles[4][1], mesh.triangles[4][2]);
  const MeshDiagnostics d = validate_mesh(mesh);
  EXPECT_EQ(d.misoriented_edges, 3);
  const std::string path = write_file("misoriented.stl", "");
  write_stl(path, mesh);
  expect_invalid(path, "inconsistently oriented: edge (v");
}

TEST(IntersectingTriangles, BoxesPinchedAtACornerTouchThereAndDoNotThrow) {
  // Two boxes sharing one corner vertex: not a surface mesh (the vertex is pinched), as a part
  // can be before its pinches are separated. The contact counts; nothing else does.
  TriMesh mesh = box();
  const TriMesh other = test::make_box(kBoxSize, 2.0 * kBoxSize);
  const auto offset = static_cast<std::int32_t>(mesh.vertices.size());
  const auto first_box = static_cast<std::int32_t>(mesh.triangles.size());  // its triangles
  mesh.vertices.insert(mesh.vertices.end(), other.vertices.begin(), other.vertices.end());
  std::int32_t shared = -1;
  for (std::int32_t v = 0; v < offset; ++v)
    if (mesh.vertices[v] == kBoxSize) shared = v;
  ASSERT_GE(shared, 0);
  for (Tri t : other.triangles) {
    for (std::int32_t& v : t) v = other.vertices[v] == kBoxSize ? shared : v + offset;
    mesh.triangles.push_back(t);
  }
  std::vector<std::array<std::int32_t, 2>> pairs;
  ASSERT_NO_THROW(pairs = intersecting_triangles(mesh, 1000));
  ASSERT_FALSE(pairs.empty());
  for (const auto& [a, b] : pairs) {
    const auto has_shared = [&](std::int32_t t) {
      return std::find(mesh.triangles[t].begin(), mesh.triangles[t].end(), shared) !=
             mesh.triangles[t].end();
    };
    EXPECT_TRUE(has_shared(a) && has_shared(b)) << a << " " << b;
    EXPECT_NE(a < first_box, b < first_box) << "one triangle of each box";
  }
  EXPECT_TRUE(intersecting_triangles(box(), 1000).empty());
}

TEST(LoadSolid, OverlappingBoxesSelfIntersect) {
  TriMesh mesh = box();
  const TriMesh other = test::make_box(kBoxSize * 0.5, kBoxSize * 1.5);
  const auto offset = static_cast<std::int32_t>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (Tri t : other.triangles)
    mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  const MeshDiagnostics d = validate_mesh(mesh);
  EXPECT_GT(d.intersecting_pairs, 0);
  EXPECT_EQ(d.boundary_edges + d.nonmanifold_edges + d.misoriented_edges, 0);
  const std::string path = write_file("overlap.obj", "");
  {
    std::ofstream obj(path);
    for (const Vec3& p : mesh.vertices)
      obj << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << "\n";
    for (const Tri& t : mesh.triangles)
      obj << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << "\n";
  }
  expect_invalid(path, "self-intersecting: triangles ");
  EXPECT_NE(load_error(path).find(" intersecting pairs)"), std::string::npos);
}

TEST(LoadSolid, ZeroAreaTriangleIsDegenerate) {
  // Split the box edge shared by triangles 0 and 1 at its midpoint m and close the crack with a
  // flat triangle (a, m, b): still closed, manifold and oriented, but one triangle has no area.
  TriMesh mesh = box();
  const Tri t0 = mesh.triangles[0];
  std::int32_t a = -1, b = -1, t1 = -1, k1 = -1;
  for (int t = 1; t < 12 && t1 < 0; ++t)
    for (int k = 0; k < 3; ++k)
      for (int j = 0; j < 3; ++j)
        if (mesh.triangles[t][k] == t0[(j + 1) % 3] && mesh.triangles[t][(k + 1) % 3] == t0[j]) {
          a = t0[j], b = t0[(j + 1) % 3], t1 = t, k1 = k;
        }
  ASSERT_GE(t1, 0);
  const auto m = static_cast<std::int32_t>(mesh.vertices.size());
  mesh.vertices.push_back(0.5 * (mesh.vertices[a] + mesh.vertices[b]));
  const std::int32_t d_vertex = mesh.triangles[t1][(k1 + 2) % 3];  // t1 is (b, a, d) rotated
  mesh.triangles[t1] = {b, m, d_vertex};
  mesh.triangles.push_back({m, a, d_vertex});
  mesh.triangles.push_back({a, m, b});
  const MeshDiagnostics d = validate_mesh(mesh);
  EXPECT_EQ(d.degenerate_triangles, 1);
  EXPECT_EQ(d.boundary_edges + d.nonmanifold_edges + d.misoriented_edges + d.nonmanifold_vertices,
            0);
  EXPECT_EQ(d.first_problem, "degenerate triangle 13 (zero area or repeated vertex)");
  const std::string path = write_file("degenerate.ply", "");
  {
    std::ofstream ply(path);
    ply.precision(17);
    ply << "ply\nformat ascii 1.0\nelement vertex " << mesh.vertices.size()
        << "\nproperty double x\nproperty double y\nproperty double z\nelement face "
        << mesh.triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const Vec3& p : mesh.vertices) ply << p.x() << ' ' << p.y() << ' ' << p.z() << "\n";
    for (const Tri& t : mesh.triangles) ply << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << "\n";
  }
  expect_invalid(path, "degenerate triangle 13");
}

TEST(LoadSolid, NanCoordinateIsReported) {
  std::string stl = ascii_stl(box());
  const std::size_t at = stl.find("vertex ") + 7;
  stl.replace(at, stl.find(' ', at) - at, "nan");
  const std::string path = write_file("nan.stl", stl);
  const TriMesh mesh = read_mesh(path);
  EXPECT_EQ(mesh.vertices.size(), 9u);  // the NaN copy is not welded with anything
  EXPECT_EQ(validate_mesh(mesh).nonfinite_vertices, 1);
  expect_invalid(path, "contains a NaN or infinite coordinate at vertex 0");
}

// Two boxes' triangles in one mesh; `inward` flips the second.
std::string two_boxes(const std::string& name, const Vec3& lo, const Vec3& hi, bool inward) {
  TriMesh mesh = test::make_box(Vec3::Zero(), Vec3(30, 30, 30));
  TriMesh second = test::make_box(lo, hi);
  if (inward) flip_orientation(second);
  const auto offset = static_cast<std::int32_t>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), second.vertices.begin(), second.vertices.end());
  for (const Tri& t : second.triangles)
    mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  const std::string path = write_file(name, "");
  write_stl(path, mesh);
  return path;
}

TEST(LoadSolid, SeveralSolidsAreRefusedACavityIsNot) {
  expect_invalid(two_boxes("disjoint.stl", Vec3(40, 0, 0), Vec3(50, 10, 10), false),
                 "has 2 separate shells, 2 of them facing outward (disjoint or nested solids)");
  expect_invalid(two_boxes("nested.stl", Vec3(10, 10, 10), Vec3(20, 20, 20), false),
                 "has 2 separate shells, 2 of them facing outward (disjoint or nested solids)");
  expect_invalid(two_boxes("inside_out.stl", Vec3(40, 0, 0), Vec3(50, 10, 10), true),
                 "has 2 separate shells: one faces inward but lies outside the outer one");
  const LoadedSolid hollow =
      load_solid(two_boxes("hollow.stl", Vec3(10, 10, 10), Vec3(20, 20, 20), true));
  EXPECT_NEAR(signed_volume(hollow.mesh), 27000.0 - 1000.0, 1e-9);
  EXPECT_FALSE(hollow.flipped);
}

TEST(LoadSolid, InvertedBoxIsFlipped) {
  TriMesh inverted = box();
  flip_orientation(inverted);
  const MeshDiagnostics d = validate_mesh(inverted);
  EXPECT_TRUE(d.ok()) << d.first_problem;
  EXPECT_DOUBLE_EQ(d.volume_mm3, -kBoxVolume);
  const std::string path = write_file("inverted.stl", "");
  write_stl(path, inverted);
  const LoadedSolid solid = load_solid(path);
  EXPECT_TRUE(solid.flipped);
  EXPECT_DOUBLE_EQ(signed_volume(solid.mesh), kBoxVolume);
  write_stl(path, box());
  EXPECT_FALSE(load_solid(path).flipped);
}

TEST(LoadSolid, ScaleAndUnitsMultiplyCoordinates) {
  const std::string path = write_file("scaled.stl", "");
  write_stl(path, box());
  const LoadedSolid solid = load_solid(path, {.scale = 0.5, .units_to_mm = 25.4});
  EXPECT_NEAR(signed_volume(solid.mesh), kBoxVolume * std::pow(0.5 * 25.4, 3), 1e-6);
}

TEST(LoadSolid, SizeSetsTheLongestSideWhateverTheScale) {
  const std::string path = write_file("sized.stl", "");
  write_stl(path, box());
  const LoadedSolid solid = load_solid(path, {.scale = 7.0, .units_to_mm = 25.4, .size_mm = 150.0});
  const Box3 b = bounding_box(solid.mesh.vertices);
  EXPECT_NEAR((b.max - b.min).maxCoeff(), 150.0, 1e-9);
  const double volume = kBoxVolume * std::pow(150.0 / kBoxSize.maxCoeff(), 3);
  EXPECT_NEAR(signed_volume(solid.mesh), volume, 1e-9 * volume);
  for (double size : {-1.0, std::numeric_limits<double>::infinity()})
    load_error(path, ErrorCode::InvalidOptions, {.size_mm = size});
}

TEST(LoadSolid, AbsurdScaleAndBadOptionsAreRejected) {
  const std::string path = write_file("scale.stl", "");
  write_stl(path, box());
  for (double scale : {1e-4, 1e5}) {
    const std::string message = load_error(path, ErrorCode::InvalidInput, {.scale = scale});
    EXPECT_EQ(message.rfind(path + ": absurd scale: bounding box diagonal is ", 0), 0u) << message;
    EXPECT_NE(message.find(" mm; use --scale or --units"), std::string::npos) << message;
  }
  for (double scale : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                       std::numeric_limits<double>::infinity()})
    load_error(path, ErrorCode::InvalidOptions, {.scale = scale});
  load_error(path, ErrorCode::InvalidOptions, {.units_to_mm = 0.0});
}

// --- malformed files: the message names the file and a location ---

TEST(ReadMesh, TruncatedBinaryStl) {
  const std::string full = write_file("full.stl", "");
  write_stl(full, box());
  const std::string bytes = read_bytes(full);
  const std::string path = write_file("truncated.stl", bytes.substr(0, bytes.size() / 2));
  expect_invalid(path,
                 "truncated binary STL: header says 12 triangles (684 bytes) but the file "
                 "has 342 bytes");
  expect_invalid(write_file("tiny.stl", "abc"), "truncated binary STL: the file has 3 bytes");
  // A binary header may start with "solid": the NUL bytes of the counts still tell it apart.
  std::string solid_header = bytes;
  solid_header.replace(0, 18, "solid binary mesh ");
  expect_invalid(write_file("truncated_solid.stl", solid_header.substr(0, 500)),
                 "truncated binary STL: header says 12 triangles (684 bytes) but the file has 500 "
                 "bytes");
}

TEST(ReadMesh, AsciiStlWithByteOrderMarkOrInCapitals) {
  expect_welded_box(read_mesh(write_file("bom.stl", "\xEF\xBB\xBF" + ascii_stl(box()))));
  std::string shouting = ascii_stl(box());
  for (char& c : shouting) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  expect_welded_box(read_mesh(write_file("shouting.stl", shouting)));
}

TEST(ReadMesh, NulByteInAsciiStlIsNamedWhereItIs) {
  std::string text = ascii_stl(box());
  const std::size_t at = text.find("vertex", text.find("vertex") + 1);  // line 5
  text.insert(at, 1, '\0');
  expect_invalid(write_file("nul.stl", text),
                 "line 5: NUL byte at byte offset " + std::to_string(at) + " of an ASCII STL");
}

TEST(ReadMesh, EmptyFile) { expect_invalid(write_file("empty.obj", ""), "empty file"); }

TEST(ReadMesh, MissingFileIsAnIoError) {
  EXPECT_EQ(load_error("/nonexistent-dir/x.stl", ErrorCode::Io),
            "/nonexistent-dir/x.stl: no such file");
}

TEST(ReadMesh, DirectoryAndDeviceAreIoErrorsWhateverTheirName) {
  const std::string dir = test::temp_dir("dir.stl");
  EXPECT_EQ(load_error(dir, ErrorCode::Io), dir + ": is a directory");
  EXPECT_EQ(load_error("/dev/null", ErrorCode::Io), "/dev/null: is not a regular file");
}

TEST(ReadMesh, FileOverTwoGibIsRefusedUnread) {
  const std::string path = write_file("sparse.stl", "");
  std::filesystem::resize_file(path, std::uintmax_t{3} << 30);  // sparse: nothing is written
  expect_invalid(path, "file of 3072 MiB; dhfcast reads meshes of at most 2 GiB");
  std::filesystem::remove(path);
}

TEST(ReadMesh, UnknownExtensionListsTheSupportedOnes) {
  const std::string path = write_file("box.xyz", "1 2 3\n");
  expect_invalid(path, "unsupported file type '.xyz'; supported: .stl, .obj, .ply, .off");
}

TEST(ReadMesh, GarbageTextFailsInEveryFormat) {
  const std::string garbage = "this is not a mesh\n\x01\x02 at all\n";
  expect_invalid(write_file("garbage.off", garbage),
                 "line 1: expected the 'OFF' header, got 'this'");
  expect_invalid(write_file("garbage.ply", garbage), "not a PLY file");
  expect_invalid(write_file("garbage.obj", garbage), "no triangles found");
  expect_invalid(write_file("garbage.stl", "solid x\n" + garbage), "line 2: unexpected 'this'");
}

TEST(ReadMesh, MalformedFilesNameTheLocation) {
  expect_invalid(write_file("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n"),
                 "line 5: vertex index 4 out of range (3 vertices defined so far)");
  expect_invalid(write_file("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
                 "line 4: bad vertex index '0'");
  expect_invalid(write_file("number.off", "OFF\n3 1 0\n0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"),
                 "line 4: bad number 'zero'");
  expect_invalid(write_file("faces.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
                 "unexpected end of file: 2 faces announced, 1 found");
  expect_invalid(write_file("facet.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"),
                 "unexpected end of file inside the facet starting at line 2");
  expect_invalid(write_file("index.ply",
                            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                            "property float y\nproperty float z\nelement face 1\n"
                            "property list uchar int vertex_indices\nend_header\n"
                            "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
                 "face 0: vertex index 3 out of range (3 vertices)");
  std::string ply = binary_ply_box(true);
  expect_invalid(write_file("cut.ply", ply.substr(0, ply.size() - 10)), "byte offset ");
  EXPECT_NE(load_error(write_file("cut2.ply", ply.substr(0, ply.size() - 10))).find("(face 5)"),
            std::string::npos);
}

}  // namespace
}  // namespace dhfcast
