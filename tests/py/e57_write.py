"""Writes points as an E57 file with pye57 (the reference libE57Format) and reads them back.

Usage: e57_write.py POINTS.xyz OUT.e57 ORACLE.xyz

The points of POINTS.xyz (world coordinates, one x y z a line) are split into two scans, the even
lines and the odd ones, each stored in its own coordinates under its own pose (a rotation
quaternion and a translation), so that the pose brings it back. The first scan also holds three
points without a return (cartesianInvalidState 2, with coordinates that are not on the surface).
The file is then read back with pye57, which applies the poses and leaves out the points without a
return, and those world coordinates are written to ORACLE.xyz with full precision. The line
`points N invalid K` says how many points were written with coordinates and without.
"""

import sys

import numpy as np
import pye57

# (w, x, y, z) and translation of each scan; the rotations are exact in binary (a turn by 120
# degrees about (1, 1, 1) and one by 180 degrees about z), so the world coordinates of the single
# precision values stored are exact in double precision too
POSES = [
    (np.array([0.5, 0.5, 0.5, 0.5]), np.array([0.25, -0.5, 1.0])),
    (np.array([0.0, 0.0, 0.0, 1.0]), np.array([-1.0, 2.0, 0.5])),
]


def rotation(q):
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def main():
    points_path, e57_path, oracle_path = sys.argv[1:4]
    world = np.loadtxt(points_path, comments="#").reshape(-1, 3)
    scans = [world[0::2], world[1::2]]
    invalid = 3
    with pye57.E57(e57_path, mode="w") as out:
        for k, (pts, (q, t)) in enumerate(zip(scans, POSES)):
            # local = R^T (world - t), so that R local + t is the world point
            local = (pts - t) @ rotation(q)
            state = np.zeros(len(local), dtype=np.int8)
            if k == 0:
                local = np.vstack([local, np.full((invalid, 3), 7.5)])
                state = np.concatenate([state, np.full(invalid, 2, dtype=np.int8)])
            data = {
                "cartesianX": local[:, 0].copy(),
                "cartesianY": local[:, 1].copy(),
                "cartesianZ": local[:, 2].copy(),
                "cartesianInvalidState": state,
            }
            out.write_scan_raw(data, name=f"station {k + 1}", rotation=q, translation=t)
    back = pye57.E57(e57_path)
    read = []
    for k in range(back.scan_count):
        scan = back.read_scan(k, transform=True, ignore_missing_fields=True)
        read.append(np.column_stack([scan["cartesianX"], scan["cartesianY"], scan["cartesianZ"]]))
    read = np.vstack(read)
    with open(oracle_path, "w") as f:
        f.write("# the E57 file's points as pye57 reads them, poses applied\n")
        for p in read:
            f.write(" ".join(repr(float(c)) for c in p) + "\n")
    print(f"points {len(read)} invalid {invalid}")


if __name__ == "__main__":
    main()
