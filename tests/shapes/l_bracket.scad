// L-bracket: a base plate and an upright joined at a right angle, a triangular gusset between
// them, two vertical bolt holes in the base (one counterbored) and two slots open at the top of
// the upright. 80 x 50 x 70 mm.
// minimum_parts: 1
//
// Upper bound (1 part, direction z): every vertical line meets the bracket in [0, h] for some
// h, or not at all, so the bracket is a double height field (in fact a single height field)
// along z. Each piece, met by a vertical line, gives an interval that starts on the base's bottom
// face z = 0 or lies on top of a piece that does: the base [0, 8]; the upright [0, 70], or
// [0, slot bottom] inside a slot's footprint, since the slots are open at the top; the gusset
// [7, top of the hypotenuse], standing on the base [0, 8] with no hole under it. The bolt
// holes and the counterbore are vertical and go down through the base's bottom face, so they
// remove all of [0, 8] or its top part. A union of intervals that all contain z = 0 is one
// interval.
// Lower bound: a solid needs at least one part.
$fn = 64;

base = [80, 50, 8];
upright = [8, 50, 70];
difference() {
  union() {
    cube(base);
    cube(upright);
    // gusset in the middle of the width, overlapping the base and the upright by 1 mm
    translate([0, 21, 0]) rotate([90, 0, 0]) mirror([0, 0, 1])
      linear_extrude(8) polygon([[7, 7], [50, 7], [50, 8], [8, 50], [7, 50]]);
  }
  // bolt holes through the base, the second counterbored from the top
  translate([62, 12, -1]) cylinder(r = 4.5, h = base.z + 2);
  translate([62, 38, -1]) cylinder(r = 4.5, h = base.z + 2);
  translate([62, 38, 5]) cylinder(r = 8, h = base.z);
  // slots open at the top of the upright, with round bottoms (lowest at z = 42)
  for (y = [12, 38]) {
    translate([-1, y, 46]) rotate([0, 90, 0]) cylinder(r = 4, h = upright.x + 2);
    translate([-1, y - 4, 46]) cube([upright.x + 2, 8, 30]);
  }
}
