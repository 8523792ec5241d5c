// The only translation unit of the tets stage that includes CGAL (Mesh_3 is slow to compile).

// Feature detection copies Boost graph edge descriptors whose unused fields GCC 12 flags as
// maybe uninitialized (a false positive inside Boost): keep -Werror builds clean.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Random.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/exceptions.h>
#include <CGAL/exude_mesh_3.h>
#include <CGAL/make_mesh_3.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>

#include "dhfcast/error.h"
#include "dhfcast/stop.h"
#include "volume_mesher.h"

namespace dhfcast::detail {

namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Domain = CGAL::Polyhedral_mesh_domain_with_features_3<Kernel, SurfaceMesh>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation, Domain::Corner_index,
                                                        Domain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

// Edges whose faces' normals differ by more than this are sharp features, sampled exactly
// (box and machined edges). Lower values also catch the facets of coarse organic meshes, whose
// protection then costs many small tets.
constexpr double kFeatureAngleDeg = 70.0;
// Mesh_3 quality bounds: boundary facets' smallest angle, tets' circumradius / shortest edge.
constexpr double kFacetAngleDeg = 25.0;
constexpr double kCellRadiusEdgeRatio = 3.0;
// Exudation works on tets whose smallest dihedral angle is below this. Without a bound it
// costs several times the meshing and does not raise the minimum, set by boundary slivers.
constexpr double kExudeSliverBoundDeg = 15.0;

SurfaceMesh to_surface_mesh(const TriMesh& surface) {
  SurfaceMesh sm;
  sm.reserve(static_cast<SurfaceMesh::size_type>(surface.vertices.size()),
             static_cast<SurfaceMesh::size_type>(3 * surface.triangles.size() / 2),
             static_cast<SurfaceMesh::size_type>(surface.triangles.size()));
  std::vector<SurfaceMesh::Vertex_index> vs;
  vs.reserve(surface.vertices.size());
  for (const Vec3& p : surface.vertices) vs.push_back(sm.add_vertex(Point(p.x(), p.y(), p.z())));
  for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
    const Tri& tri = surface.triangles[t];
    if (sm.add_face(vs[tri[0]], vs[tri[1]], vs[tri[2]]) == SurfaceMesh::null_face())
      throw Error(ErrorCode::TetrahedralizationFailed,
                  "tets: the input surface is not a 2-manifold at triangle " + std::to_string(t));
  }
  return sm;
}

Error mesher_error(const char* step, const CGAL::Failure_exception& e) {
  return Error(ErrorCode::TetrahedralizationFailed,
               std::string("tets: CGAL ") + step + " failed: " + e.message());
}
}  // namespace

struct VolumeMesher::Impl {
  SurfaceMesh surface;
  std::uint32_t seed = 0;
  CGAL::Random rng;  // the domain's generator for its initial surface points
  std::optional<Domain> domain;
  std::optional<Tree> tree;  // exact input triangles, for measuring the boundary's distance
  Complex c3t3;
};

VolumeMesher::VolumeMesher(const TriMesh& surface, std::uint32_t seed) : impl_(new Impl) {
  impl_->surface = to_surface_mesh(surface);
  impl_->seed = seed;
  try {
    impl_->domain.emplace(impl_->surface, &impl_->rng);
    impl_->domain->detect_features(kFeatureAngleDeg);
  } catch (const CGAL::Failure_exception& e) {
    throw mesher_error("feature detection", e);
  }
  const auto [first, last] = faces(impl_->surface);
  impl_->tree.emplace(first, last, impl_->surface);
  impl_->tree->accelerate_distance_queries();
}

VolumeMesher::~VolumeMesher() = default;

RefineResult VolumeMesher::refine(const MeshSizes& sizes, std::size_t max_vertices,
                                  double max_seconds) {
  namespace params = CGAL::parameters;
  // Both generators the mesher draws from restart at the seed, so every run is reproducible.
  impl_->rng = CGAL::Random(impl_->seed);
  CGAL::get_default_random() = CGAL::Random(impl_->seed);
  // Feature edges are sampled at the boundary facets' size.
  const Criteria criteria(
      params::edge_size = sizes.facet_size_mm, params::facet_angle = kFacetAngleDeg,
      params::facet_size = sizes.facet_size_mm, params::facet_distance = sizes.facet_distance_mm,
      params::cell_radius_edge_ratio = kCellRadiusEdgeRatio,
      params::cell_size = sizes.cell_size_mm);
  // Mesh_3 has no callback: its own checks of a vertex budget and of a stop flag end a run. A
  // watchdog raises the flag on request_stop() or at the time budget (feature protection can
  // loop without adding vertices: CGAL's mpi_triang.off, sharp edges 1 um apart).
  CGAL::Mesh_error_code stopped = CGAL::CGAL_MESH_3_NO_ERROR;
  std::atomic<bool> halt{false};
  bool timed_out = false;
  std::mutex mutex;
  std::condition_variable finished;
  bool done = false;
  std::thread watchdog([&] {
    const auto deadline = std::chrono::steady_clock::now() +
                          std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                              std::chrono::duration<double>(max_seconds));
    std::unique_lock lock(mutex);
    while (!done) {
      if (stop_flag().load()) {
        halt = true;
        return;
      }
      if (std::chrono::steady_clock::now() >= deadline) {
        timed_out = true;
        halt = true;
        return;
      }
      finished.wait_for(lock, std::chrono::milliseconds(50));
    }
  });
  const auto stop_watchdog = [&] {
    {
      const std::lock_guard lock(mutex);
      done = true;
    }
    finished.notify_all();
    watchdog.join();
  };
  try {
    impl_->c3t3 = CGAL::make_mesh_3<Complex>(
        *impl_->domain, criteria, params::no_perturb(), params::no_exude(),
        params::mesh_3_options(params::maximal_number_of_vertices = max_vertices,
                               params::pointer_to_error_code = &stopped,
                               params::pointer_to_stop_atomic_boolean = &halt));
  } catch (const CGAL::Failure_exception& e) {
    stop_watchdog();
    throw mesher_error("Mesh_3", e);
  }
  stop_watchdog();
  if (stopped == CGAL::CGAL_MESH_3_STOPPED) throw_if_stop_requested();
  return {.tets = static_cast<std::int64_t>(impl_->c3t3.number_of_cells_in_complex()),
          .capped = stopped == CGAL::CGAL_MESH_3_MAXIMAL_NUMBER_OF_VERTICES_REACHED,
          .timed_out = stopped == CGAL::CGAL_MESH_3_STOPPED && timed_out};
}

void VolumeMesher::exude() {
  namespace params = CGAL::parameters;
  try {
    // No time limit: a timed exudation would depend on the machine's speed.
    CGAL::exude_mesh_3(impl_->c3t3, params::time_limit = 0,
                       params::sliver_bound = kExudeSliverBoundDeg);
  } catch (const CGAL::Failure_exception& e) {
    throw mesher_error("sliver exudation", e);
  }
}

TetMesh VolumeMesher::extract() const {
  TetMesh out;
  out.tets.reserve(impl_->c3t3.number_of_cells_in_complex());
  // Vertices are numbered in order of first use: the cell order is deterministic, so is this.
  std::unordered_map<Triangulation::Vertex_handle, std::int32_t> index;
  for (auto c = impl_->c3t3.cells_in_complex_begin(); c != impl_->c3t3.cells_in_complex_end();
       ++c) {
    Tet tet;
    for (int i = 0; i < 4; ++i) {
      const Triangulation::Vertex_handle v = c->vertex(i);
      const auto [it, added] = index.emplace(v, static_cast<std::int32_t>(out.vertices.size()));
      if (added) {
        const auto& p = v->point();
        out.vertices.emplace_back(CGAL::to_double(p.x()), CGAL::to_double(p.y()),
                                  CGAL::to_double(p.z()));
      }
      tet[i] = it->second;
    }
    out.tets.push_back(tet);
  }
  return out;
}

double VolumeMesher::max_distance_to_surface(const std::vector<Vec3>& points) const {
  double max_sq = 0.0;
  for (const Vec3& p : points)
    max_sq = std::max(max_sq, impl_->tree->squared_distance(Point(p.x(), p.y(), p.z())));
  return std::sqrt(max_sq);
}

}  // namespace dhfcast::detail
