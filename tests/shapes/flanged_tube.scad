// Flanged tube: a tube with a flange at one end, four bolt holes in the flange and a raised
// collar where the tube meets the flange. Axis z. 70 x 70 x 80 mm.
// minimum_parts: 1
//
// Upper bound (1 part, direction z): the tube is a solid of revolution about z (its profile
// below) minus vertical holes, so a vertical line at distance r from the axis meets it in:
// nothing for r < 11 (the bore); [0, 80] for 11 <= r <= 15 (the tube wall); [0, 14] for
// 15 < r <= 20 (the collar); [0, 10] for 20 < r <= 35 (the flange), or nothing inside a bolt
// hole, which goes through the whole flange. One interval or nothing: a double height field
// along z.
// Lower bound: a solid needs at least one part.
$fn = 64;

difference() {
  rotate_extrude() polygon([[11, 0], [35, 0], [35, 10], [20, 10], [20, 14], [15, 14],
                            [15, 80], [11, 80]]);
  for (a = [45 : 90 : 315]) rotate([0, 0, a]) translate([27, 0, -1]) cylinder(r = 4, h = 12);
}
