// Dumbbell: two chamfered weight discs on a bar with a grip ring, all coaxial about the x axis.
// 140 x 60 x 60 mm.
// minimum_parts: 1
//
// Along its own axis x it is no double height field (a line parallel to x at distance 20 from
// the axis meets both weights and nothing between), yet one part suffices.
// Upper bound (1 part, direction y): every piece is a convex solid of revolution about the x
// axis, so the cross-section of the dumbbell by a plane x = const is a disc centred on the axis
// (the largest of the pieces' discs there). A line parallel to y lies in such a plane and meets
// the disc in one interval, or misses it. So the dumbbell is a double height field along y (any
// direction orthogonal to x), cast in a mold split at the plane y = 0.
// Lower bound: a solid needs at least one part.
$fn = 64;

module weight(x0) {
  // a disc 25 mm thick, radius 30, chamfered 4 mm on both faces
  translate([x0, 0, 0]) rotate([0, 90, 0]) {
    cylinder(r1 = 26, r2 = 30, h = 4);
    translate([0, 0, 4]) cylinder(r = 30, h = 17);
    translate([0, 0, 21]) cylinder(r1 = 30, r2 = 26, h = 4);
  }
}
weight(-70);
weight(45);
rotate([0, 90, 0]) translate([0, 0, -46]) cylinder(r = 8, h = 92);
rotate([0, 90, 0]) translate([0, 0, -15]) cylinder(r = 11, h = 30);
