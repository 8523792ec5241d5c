// Connecting rod: a genus-2 plate. A big-end boss and a small-end boss, each with a bore, joined
// by a thinner web; everything symmetric about the mid-plane z = 0. 122 x 40 x 20 mm.
// minimum_parts: 1
//
// Upper bound (1 part, direction z): a vertical line meets the big boss in [-10, 10], the small
// boss in [-8, 8] and the web in [-4, 4] (whichever of them lie above its point of the plane):
// intervals that all contain z = 0, so their union is one interval. The two bores are vertical
// and go through the whole height of their bosses (they are cut after the union), so a line
// inside a bore meets nothing. Every vertical line thus meets the rod in one interval or not at
// all: it is a double height field along z, cast in a mold split at z = 0. Two holes do not
// prevent this: genus is no obstacle when the holes are parallel to the direction.
// Lower bound: a solid needs at least one part.
$fn = 64;

big = [0, 0];
small = [90, 0];
difference() {
  union() {
    translate([big.x, big.y, -10]) cylinder(r = 20, h = 20);
    translate([small.x, small.y, -8]) cylinder(r = 12, h = 16);
    // tapered web between the bosses
    translate([0, 0, -4]) linear_extrude(8)
      polygon([[0, -14], [90, -8], [90, 8], [0, 14]]);
  }
  translate([big.x, big.y, -11]) cylinder(r = 12, h = 22);
  translate([small.x, small.y, -9]) cylinder(r = 6, h = 18);
}
