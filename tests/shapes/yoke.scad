// Yoke (clevis): a base 60 x 30 x 15 mm with a shank below it, and two arms 12 mm thick
// (18 <= |x| <= 30) rising from it, rounded at the top about the axis of a cross hole (radius 7,
// along x, at y = 0, z = 45) through both arms. A bore (radius 8, along z) goes through the
// shank and the base. 60 x 30 x 85 mm.
// minimum_parts: 2
//
// Lower bound (2): the cross hole goes through an arm (a slab 12 mm thick around it), so by the
// through-hole lemma the yoke is a double height field along no direction but +-x. Along x, the
// line y = 0, z = 30 meets the arm x <= -18, then the empty gap between the arms, then the arm
// x >= 18. No direction works for the whole yoke.
// Upper bound (2 parts, both along y): cut by the plane y = 0, which holds the axes of the cross
// hole and of the bore. Every piece (base, shank, arms, hole, bore) meets a line parallel to y
// in an interval centred on y = 0, or not at all: the arms' and the base's sections by a plane
// x = const are convex and symmetric about y = 0, the shank, the hole and the bore are
// cylinders whose axes lie in the plane y = 0. So at (x, z) the yoke is {b <= |y| <= a} (the
// pieces' union minus the holes), and its half y <= 0 is the one interval [-a, -b].
$fn = 64;

difference() {
  union() {
    translate([-30, -15, 0]) cube([60, 30, 15]);
    translate([0, 0, -25]) cylinder(r = 12, h = 26);
    for (x0 = [-30, 18]) translate([x0, 0, 0]) rotate([0, 90, 0]) linear_extrude(12)
      // the arm's section in the (-z, y) plane of the rotated frame: a slot, rounded at the top
      hull() { translate([-45, 0]) circle(r = 15); translate([-1, -15]) square([1, 30]); }
  }
  translate([-31, 0, 45]) rotate([0, 90, 0]) cylinder(r = 7, h = 62);
  translate([0, 0, -26]) cylinder(r = 8, h = 42);
}
