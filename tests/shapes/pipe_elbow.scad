// Pipe elbow: a 90-degree bend (bend radius 40) of a pipe (outer radius 12, bore 8) with a
// straight end 25 mm long and a flange (radius 22, 6 mm thick, two bolt holes) on each end.
// The pipe's centre line lies in the plane y = 0: it runs down the line x = 40 to z = -25 and
// left along the line z = 40 to x = -25. 87 x 44 x 87 mm.
// minimum_parts: 2
//
// Lower bound (2): each straight end's bore goes through its pipe (a tube around it, between the
// flange and the bend), so by the through-hole lemma the end along z allows no direction but
// +-z and the end along x none but +-x. No direction works for the whole elbow.
// Upper bound (2 parts, both along y): cut by the plane y = 0. The elbow is three pieces that
// meet only on the planes z = 0 and x = 0: each straight end (a flanged pipe, revolved about its
// axis, minus two bolt holes whose axes lie in the plane y = 0) and the bend (an annulus
// revolved about the y axis). A line parallel to y at (x, z) meets one piece, in a set
// {b <= |y| <= a} (a pipe wall or flange, symmetric and convex across y = 0, minus a bore or
// bolt hole that is too), so the half y <= 0 meets it in the one interval [-a, -b].
$fn = 64;

// a straight end along z, from z = -25 to 0: pipe and flange, with the bolt holes at x = +-16
module end() {
  difference() {
    translate([0, 0, -25]) rotate_extrude() polygon([[8, 0], [22, 0], [22, 6], [12, 6], [12, 25],
                                                     [8, 25]]);
    for (s = [-1, 1]) translate([16 * s, 0, -26]) cylinder(r = 3.5, h = 8);
  }
}
translate([40, 0, 0]) end();
translate([0, 0, 40]) rotate([0, 90, 0]) end();
// the bend, from (40, 0, 0) to (0, 0, 40)
rotate([90, 0, 0]) rotate_extrude(angle = 90) translate([40, 0]) difference() {
  circle(r = 12);
  circle(r = 8);
}
