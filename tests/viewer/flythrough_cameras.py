#!/usr/bin/env python3
"""A fly-through between COLMAP cameras, as a viewer's user orbits a scene: the cameras of
cameras.json (Inria's list, as `watergs render` writes it) from FIRST to LAST in file order, with
STEPS - 1 frames between each pair: centres interpolated along the orbit (direction and distance
from the origin interpolated apart), orientations by quaternion slerp.
  flythrough_cameras.py CAMERAS.json FIRST LAST STEPS OUT.json"""
import json
import math
import sys


def to_quaternion(r):  # rotation matrix (rows) -> (w, x, y, z)
    t = r[0][0] + r[1][1] + r[2][2]
    if t > 0:
        s = 2 * math.sqrt(1 + t)
        return [s / 4, (r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s]
    i = max(range(3), key=lambda k: r[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2 * math.sqrt(1 + r[i][i] - r[j][j] - r[k][k])
    q = [0.0] * 4
    q[0] = (r[k][j] - r[j][k]) / s
    q[1 + i] = s / 4
    q[1 + j] = (r[j][i] + r[i][j]) / s
    q[1 + k] = (r[k][i] + r[i][k]) / s
    return q


def to_matrix(q):
    w, x, y, z = q
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def slerp(a, b, t):
    dot = sum(u * v for u, v in zip(a, b))
    if dot < 0:
        b, dot = [-v for v in b], -dot
    if dot > 0.9995:
        q = [u + t * (v - u) for u, v in zip(a, b)]
    else:
        angle = math.acos(dot)
        wa, wb = math.sin((1 - t) * angle) / math.sin(angle), math.sin(t * angle) / math.sin(angle)
        q = [wa * u + wb * v for u, v in zip(a, b)]
    n = math.sqrt(sum(v * v for v in q))
    return [v / n for v in q]


def along_orbit(p, q, t):
    rp, rq = math.dist(p, [0, 0, 0]), math.dist(q, [0, 0, 0])
    d = [(1 - t) * u / rp + t * v / rq for u, v in zip(p, q)]
    n = math.dist(d, [0, 0, 0])
    r = (1 - t) * rp + t * rq
    return [r * v / n for v in d]


def main():
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    cameras = json.load(open(sys.argv[1]))
    first, last, steps = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    if not (0 <= first < last < len(cameras)) or steps < 1:
        sys.exit(f"flythrough_cameras: need 0 <= FIRST < LAST < {len(cameras)} and STEPS >= 1")
    frames = []
    for c in range(first, last + 1):
        a = cameras[c]
        for s in range(steps if c < last else 1):
            t = s / steps
            frame = dict(a)
            if s > 0:
                b = cameras[c + 1]
                frame["position"] = along_orbit(a["position"], b["position"], t)
                frame["rotation"] = to_matrix(slerp(to_quaternion(a["rotation"]),
                                                    to_quaternion(b["rotation"]), t))
            frame["id"] = len(frames)
            frame["img_name"] = f"frame_{len(frames):03d}"
            frame["between"] = [a["img_name"], cameras[min(c + 1, last)]["img_name"], t]
            frames.append(frame)
    json.dump(frames, open(sys.argv[5], "w"), indent=1)


if __name__ == "__main__":
    main()
