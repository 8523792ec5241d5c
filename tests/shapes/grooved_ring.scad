// Grooved ring: a thick ring (outer radius 35, bore radius 25, 30 mm high, axis z) with an
// internal groove (out to radius 29, 12 <= z <= 18) in its bore, like a bearing housing's
// circlip groove, and a 2 mm chamfer on both outer edges. 70 x 70 x 30 mm.
// minimum_parts: 2
//
// Lower bound (2): the bore goes through the ring (a tube around it for 0 <= z <= 10), so by the
// through-hole lemma no direction but +-z can work. Along z, the line at distance 27 from the
// axis meets the ring below the groove (z <= 12) and above it (z >= 18), and nothing between:
// the groove is an undercut seen from no direction. No direction works for the whole ring.
// Upper bound (2 parts, both along z): cut at the groove's mid-plane z = 15. A vertical line at
// distance r from the axis meets the lower half in: nothing for r < 25; [0, 12] for
// 25 <= r < 29; [0, 15] for 29 <= r <= 33; [z_c(r), 15] for 33 < r <= 35, z_c being the
// chamfer's height. The upper half is its mirror image.
$fn = 64;

rotate_extrude() polygon([[25, 0], [33, 0], [35, 2], [35, 28], [33, 30], [25, 30], [25, 18],
                          [29, 18], [29, 12], [25, 12]]);
