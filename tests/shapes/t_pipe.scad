// T-pipe: a straight pipe along x (outer radius 15, bore 11, 120 mm long) and a branch along z
// (outer radius 12, bore 8) rising from its top to z = 60; the branch's bore opens into the main
// bore. 120 x 30 x 75 mm.
// minimum_parts: 2
//
// Lower bound (2): the main bore goes through the pipe (a tube around it for 20 <= x <= 60), so
// by the through-hole lemma no direction but +-x can work; the branch bore goes through the
// branch (a tube around it for 20 <= z <= 60), so no direction but +-z can. No direction works
// for the whole T.
// Upper bound (2 parts, both along z): cut at z = 0, the main pipe's axial plane. The lower part
// is half a tube, open at the top: a vertical line at (x, y) meets it in
// [-sqrt(15^2 - y^2), -sqrt(11^2 - y^2)] for |y| < 11 and [-sqrt(15^2 - y^2), 0] for
// 11 <= |y| <= 15. In the upper part, the outer solids (main pipe and branch) meet a vertical
// line in intervals that start at or below z = 0, the bores remove all of z > 0 inside the
// branch bore and [0, sqrt(11^2 - y^2)) inside the main bore: what remains is nothing, or
// [sqrt(11^2 - y^2), top] or [0, top]. One interval or nothing everywhere.
$fn = 64;

difference() {
  union() {
    rotate([0, 90, 0]) translate([0, 0, -60]) cylinder(r = 15, h = 120);
    cylinder(r = 12, h = 60);
  }
  rotate([0, 90, 0]) translate([0, 0, -61]) cylinder(r = 11, h = 122);
  cylinder(r = 8, h = 61);
}
