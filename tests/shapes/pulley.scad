// Grooved pulley: a V-belt groove around the rim, a thin web with five lightening holes, a hub
// standing out 3 mm on both sides, and a keyed bore. Axis z; the groove's mid-plane is z = 12.
// 100 x 100 x 30 mm.
// minimum_parts: 2
//
// Lower bound (2): each lightening hole goes through the web (a slab 8 mm thick around it), so
// by the through-hole lemma the pulley is a double height field along no direction but +-z.
// Along z, the vertical line at distance 46 from the axis crosses the groove: it meets the rim below the
// groove (z <= 7) and above it (z >= 17) and nothing in between. So no direction works for the
// whole pulley: at least 2 parts.
// Upper bound (2 parts, both along z): cut at the groove's mid-plane z = 12. The profile below
// is revolved about z; a vertical line at distance r from the axis meets the lower half in:
// [-3, 12] on the hub (6 <= r <= 16), [8, 12] on the web (16 < r < 38), [0, 12] on the rim
// inside the groove's bottom (38 <= r <= 42), and [0, z(r)] where the groove's lower flank
// (from (50, 4) to (42, 10)) is at height z(r) (42 < r <= 50). The bore, the keyway and the
// lightening holes are vertical prisms through everything above their footprints (the holes lie
// within 16 < r < 38, over the web alone), so a line inside one meets nothing. One interval or
// nothing everywhere: the lower half is a double height field along z, and the upper half is
// its mirror image. The upper half lifts off along +z (the halves only touch on z = 12).
$fn = 64;

difference() {
  rotate_extrude() polygon([
    [0, -3], [16, -3], [16, 8], [38, 8], [38, 0], [50, 0], [50, 4], [42, 10], [42, 14],
    [50, 20], [50, 24], [38, 24], [38, 16], [16, 16], [16, 27], [0, 27]]);
  // keyed bore
  translate([0, 0, -4]) cylinder(r = 6, h = 32);
  translate([0, -2, -4]) cube([8.5, 4, 32]);
  // lightening holes in the web
  for (a = [0 : 72 : 288]) rotate([0, 0, a + 36]) translate([27, 0, 7]) cylinder(r = 8, h = 10);
}
