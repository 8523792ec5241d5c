// Spool: two flanges (radius 40, 8 mm thick) on a core (radius 18, 80 mm long) with a bore
// (radius 8) along the axis z, and four holes through each flange. 80 x 80 x 80 mm.
// minimum_parts: 2
//
// Lower bound (2): the bore goes through the core (a tube around it for 8 <= z <= 72), so by the
// through-hole lemma no direction but +-z can work. Along z, the line x = 25, y = 0 (between
// the flange holes) meets both flanges and nothing between them. No direction works for the
// whole spool.
// Upper bound (2 parts, both along z): cut at the mid-plane z = 40. A vertical line at distance
// r from the axis meets the lower half in: nothing for r < 8; [0, 40] for 8 <= r <= 18; [0, 8]
// for 18 < r <= 40, or nothing inside a flange hole (they go through the flange). The upper half
// is its mirror image.
$fn = 64;

difference() {
  union() {
    cylinder(r = 40, h = 8);
    translate([0, 0, 72]) cylinder(r = 40, h = 8);
    translate([0, 0, 1]) cylinder(r = 18, h = 78);
  }
  translate([0, 0, -1]) cylinder(r = 8, h = 82);
  for (a = [45 : 90 : 315]) rotate([0, 0, a]) translate([29, 0, -1]) cylinder(r = 6, h = 82);
}
