// Bottle: a cylindrical body (outer radius 30, wall 3, floor 4), a conical shoulder and a
// straight neck (outer radius 12, bore radius 9) open at the top. Axis z. 60 x 60 x 130 mm.
// The profile below is revolved about z.
// minimum_parts: 2
//
// Lower bound (2), by the vessel lemma: the inside V (cavity and bore) is bounded by the
// bottle's walls everywhere except its mouth, the disc of radius 9 at z = 130, and V contains
// the ball of radius 27 centred at (0, 0, 46.5). As 27 > 9, for every direction d some line
// parallel to d crosses the ball and misses the mouth; from a point of the ball, both of its
// rays leave V through a wall, so the line meets the bottle on both sides of an empty point.
// The bottle is a double height field along no direction: 2 parts at least.
// Upper bound (2 parts, both along z): cut at z = 50, across the body. The lower part is an
// open cup: a vertical line at distance r from the axis meets it in [0, 4] for r < 27 and
// [0, 50] for 27 <= r <= 30. The upper part is open below (the cut) and above (the bore): a
// vertical line meets it in nothing for r < 9; [z_in(r), 130] for 9 <= r <= 12, where z_in is
// the height of the inner shoulder (from (27, 89) to (9, 109)); [z_in(r), z_out(r)] for
// 12 < r < 27, z_out being the outer shoulder (from (30, 90) to (12, 110)); [50, z_out(r)] for
// 27 <= r <= 30. One interval or nothing everywhere.
$fn = 64;

rotate_extrude() polygon([[0, 0], [30, 0], [30, 90], [12, 110], [12, 130], [9, 130], [9, 109],
                          [27, 89], [27, 4], [0, 4]]);
