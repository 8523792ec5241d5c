// Private to check: what the checks share once the folder is read.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "dhfcast/check.h"
#include "dhfcast/types.h"
#include "surface_index.h"

namespace dhfcast::detail {

// A part of the folder, with its meshes indexed for queries.
struct CheckedPart {
  std::int32_t id = 0;
  std::string mesh_file;           // as written in decomposition.json
  Vec3 direction = Vec3::UnitZ();  // normalized
  Vec3 removal = Vec3::UnitZ();    // normalized; the way it leaves the assembly
  double volume_mm3 = 0.0;         // from decomposition.json (the mesh's when missing there)
  SurfaceIndex solid;
  bool molds_listed = false;  // decomposition.json names mold halves, or why there are none
  std::string mold_error;    // its "molds": {"error": ...}
  // Channels (sprues, then vents) cut into the mold: an axis from mouth to exit, a diameter.
  struct Channel {
    Vec3 mouth = Vec3::Zero(), exit = Vec3::Zero();
    double diameter_mm = 0.0;
  };
  std::vector<Channel> channels;
  std::int32_t sprues = 0, vents = 0, keys = 0;
  std::optional<SurfaceIndex> mold_up, mold_down;  // those that could be read
};

// Everything the geometric checks need.
struct CheckContext {
  CheckOptions options;
  std::vector<CheckedPart> parts;       // in decomposition.json order
  std::vector<std::int32_t> order;      // indices into parts, in assembly order; empty when
                                        // assembly_order is not a permutation of the ids
  // Holes carved out of parts: inside the input, in no part.
  struct CarvedVoid {
    std::int32_t part = -1;
    double volume_mm3 = 0.0;
    SurfaceIndex solid;
  };
  std::vector<CarvedVoid> voids;
  std::optional<SurfaceIndex> input;    // the input mesh (CheckOptions::input_mesh)
  double json_input_volume_mm3 = 0.0;   // 0 when absent
  std::optional<Box3> json_input_bbox;  // input.bbox_mm
};

// The geometric checks; each returns a finished item (name, verdict, summary, figures).
CheckItem check_coverage(const CheckContext& context);
CheckItem check_dhf(const CheckContext& context);
CheckItem check_assembly(const CheckContext& context);
CheckItem check_molds(const CheckContext& context);
CheckItem check_fidelity(const CheckContext& context);

// A point p travelling along +dir from where it is to infinity, against a solid.
struct Sweep {
  bool resolved = false;   // the crossings were consistent (after at most two tiny shifts of p)
  bool blocked = false;    // the path goes deeper than epsilon into the solid
  double inside_mm = 0.0;  // length of the path inside the solid
};
// Stretches inside shorter than 2 * epsilon_mm that start outside cannot be deeper than
// epsilon_mm; longer ones are sampled every epsilon_mm / 2 for their distance to the surface.
Sweep sweep(const SurfaceIndex& solid, const Vec3& p, const Vec3& dir, double epsilon_mm);

// Does the ray p + t * dir, t >= 0, meet the box?
bool ray_meets_box(const Vec3& p, const Vec3& dir, const Box3& box);

// printf-style formatting into a std::string (one summary line).
std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));

// "part 3".
std::string part_name(const CheckedPart& part);

}  // namespace dhfcast::detail
