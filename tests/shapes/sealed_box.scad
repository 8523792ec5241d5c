// Sealed box: a rectangular block 90 x 70 x 50 mm with walls 10 mm thick all round an enclosed
// rectangular void 70 x 50 x 30 mm, and four feet 4 mm high under its corners. 90 x 70 x 54 mm.
// minimum_parts: 2
//
// Lower bound (2), by the enclosed-void lemma: take any direction d and any point c of the void;
// the two rays from c along +d and -d each leave the void through a wall, so the line meets
// the box on both sides of the empty point c. No direction makes the whole box a double height
// field.
// Upper bound (2 parts, both along z): cut at z = 25, through the void. The lower part is a tray
// open at the top: a vertical line meets it in [-4, 10] or [0, 10] (a foot under the floor, or
// the floor alone) inside the void's footprint, [-4, 25] or [0, 25] on the walls. The upper
// part is a lid with a recess open below: [40, 50] inside the footprint, [25, 50] on the walls.
$fn = 48;

difference() {
  union() {
    cube([90, 70, 50]);
    for (x = [10, 80], y = [10, 60]) translate([x, y, -4]) cylinder(r = 6, h = 5);
  }
  translate([10, 10, 10]) cube([70, 50, 30]);
}
