// Mug: a cylindrical cup (outer radius 30, cavity radius 26 and depth 90 above a 6 mm floor)
// with a rectangular loop handle on the +x side. 88 x 60 x 96 mm.
// minimum_parts: 2
//
// The handle: two arms 8 mm thick and 16 mm wide (|y| <= 8) at 27 <= z <= 35 and
// 61 <= z <= 69, running from inside the wall (x = 28) out to a grip at 50 <= x <= 58; the
// opening between them, 30 < x < 50 and 35 < z < 61, is empty. Let d make an angle t with the
// z axis (0 <= t <= 90 degrees; -d is the same line family).
// Lower bound (2): if tan t < 16/26, the line parallel to d through the opening's centre
// (40, 0, 48) reaches the heights z = 35 and z = 61 of the arms' faces 13 mm away vertically,
// having moved at most 13 tan t < 8 mm sideways (so |x - 40| < 10 and |y| < 8): it meets both
// arms, and the opening's centre between them is empty. If tan t > 52/90, the line parallel to d
// through the cavity's centre (0, 0, 51) leaves the cavity's side wall (radius 26) at heights
// within 51 +- 26 / tan t, inside the wall's height range 6 < z < 96 (as 26 / tan t < 45): it meets the
// wall on both sides of the empty centre. Since 52/90 < 16/26, every direction is one of the
// two: the mug is a double height field along no direction, and needs 2 parts at least.
// Upper bound (2 parts): the strip x >= 27, |y| <= 8 (the handle and the piece of wall behind
// it) along y, and the rest along z. A line parallel to y at (x, z) with x >= 27 > 26 misses
// the cavity; it meets the cup where |y| <= sqrt(30^2 - x^2), and the handle in all of
// |y| <= 8 or nothing: two intervals centred on y = 0, so one. A vertical line outside the
// strip (the strip taken out of the cup) meets the cup in [0, 6] (inside the cavity's footprint) or [0, 96] (on the wall), and
// no handle (the handle lies in the strip).
$fn = 64;

rotate_extrude() polygon([[0, 0], [30, 0], [30, 96], [26, 96], [26, 6], [0, 6]]);
difference() {
  translate([28, -8, 27]) cube([30, 16, 42]);
  translate([30, -9, 35]) cube([20, 18, 26]);
}
