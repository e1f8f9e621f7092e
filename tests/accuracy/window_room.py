#!/usr/bin/env python3
"""window_room.py OUT_DIR [--closed] [--no-ground]: an interior lit through a window.

Writes OUT_DIR/room.obj, room.mtl and pts.txt: a 6 x 3 x 5 m room (x, y up,
z) of single-sided walls facing in, a 2 x 1.4 m window in its z = 5 wall,
on a 46 m ground plane 1 cm below its floor, and 25 probe points 1 m above
the floor. No lights: gi-bake and gi-accuracy add the default sun and sky.
--closed shuts the window (the reference inside is then 0: all light read
there leaked through the walls); --no-ground leaves the ground out (the
scene is then the room alone, and its cascade six times finer).

  python3 tests/accuracy/window_room.py out/room
  build/bin/gi-accuracy --scene out/room/room.obj --probes out/room/pts.txt \\
      --at 3,1.2,2.5 --no-workloads --no-views --no-by-light --no-cycles

docs/accuracy-notes.md reads the figures ("Interiors behind thin walls").
"""
import os
import sys


def main(argv):
    args = [a for a in argv[1:] if not a.startswith("--")]
    flags = {a for a in argv[1:] if a.startswith("--")}
    unknown = flags - {"--closed", "--no-ground"}
    if len(args) != 1 or unknown:
        sys.stderr.write(__doc__)
        return 2
    out = args[0]
    os.makedirs(out, exist_ok=True)
    verts, faces = [], []

    def quad(a, b, c, d):
        n = len(verts)
        verts.extend([a, b, c, d])
        faces.append((n + 1, n + 2, n + 3, n + 4))

    X, Y, Z = 6.0, 3.0, 5.0
    quad((0, 0, 0), (0, 0, Z), (X, 0, Z), (X, 0, 0))  # floor, facing up
    quad((0, Y, 0), (X, Y, 0), (X, Y, Z), (0, Y, Z))  # ceiling, facing down
    quad((0, 0, 0), (0, Y, 0), (0, Y, Z), (0, 0, Z))  # x = 0, facing +x
    quad((X, 0, 0), (X, 0, Z), (X, Y, Z), (X, Y, 0))  # x = 6, facing -x
    quad((0, 0, 0), (X, 0, 0), (X, Y, 0), (0, Y, 0))  # z = 0, facing +z

    def wall_z(x0, x1, y0, y1):  # z = 5, facing -z
        quad((x0, y0, Z), (x0, y1, Z), (x1, y1, Z), (x1, y0, Z))

    wall_z(0, 2, 0, Y)
    wall_z(4, X, 0, Y)
    wall_z(2, 4, 0, 0.8)
    wall_z(2, 4, 2.2, Y)
    if "--closed" in flags:
        wall_z(2, 4, 0.8, 2.2)
    if "--no-ground" not in flags:
        quad((-20, -0.01, -20), (-20, -0.01, 30), (26, -0.01, 30), (26, -0.01, -20))
    with open(os.path.join(out, "room.mtl"), "w") as f:
        f.write("newmtl white\nKd 0.7 0.7 0.7\n")
    with open(os.path.join(out, "room.obj"), "w") as f:
        f.write("mtllib room.mtl\nusemtl white\n")
        for v in verts:
            f.write("v %g %g %g\n" % v)
        for q in faces:
            f.write("f %d %d %d %d\n" % q)
    with open(os.path.join(out, "pts.txt"), "w") as f:
        for x in (0.75, 1.75, 3, 4.25, 5.25):
            for z in (0.75, 1.75, 2.75, 3.75, 4.5):
                f.write("%g 1 %g\n" % (x, z))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
