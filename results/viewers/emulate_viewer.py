#!/usr/bin/env python3
"""A viewer's per-splat conventions applied to a 3DGS PLY, for `watergs render` to render: if
watergs' render of the result matches the viewer's screenshot, those conventions are the gap.

  emulate_viewer.py MODEL.ply OUT_DIR OPS [--cameras cameras.json --cull LIMIT]

OPS, comma-separated:
  sh0      f_rest zeroed (the viewer evaluates SH degree 0: gaussian-splats-3d's default)
  clamp01  base colour 0.5 + C0 f_dc clamped to [0, 1] (gaussian-splats-3d stores it in 8 bits;
           watergs, like Inria, clamps the colour at 0 only)
Writes OUT_DIR/model.ply, or with --cameras and --cull, OUT_DIR/<img_name>.ply for each camera:
the splats whose centre projects inside LIMIT times the image's NDC square and in front of the
camera (gaussian-splats-3d culls centres outside 1.2; watergs, like Inria, keeps every splat in
front of the near plane whose 3-sigma footprint touches the image). Binary little-endian
float-only PLYs (what watergs and Inria's trainer write).
"""
import argparse
import json
import os

import numpy as np

SH_C0 = 0.28209479177387814


def read_ply(path):
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            line = f.readline()
            if not line:
                raise ValueError(f"{path}: no end_header")
            header += line
        lines = header.decode().split("\n")
        if "format binary_little_endian 1.0" not in lines:
            raise ValueError(f"{path}: not binary little-endian")
        props = [l.split()[-1] for l in lines if l.startswith("property")]
        if any(l.split()[1] != "float" for l in lines if l.startswith("property")):
            raise ValueError(f"{path}: only float properties")
        count = int(next(l for l in lines if l.startswith("element vertex")).split()[-1])
        data = np.frombuffer(f.read(count * 4 * len(props)), dtype="<f4").reshape(count, len(props)).copy()
    return header, props, data


def write_ply(path, header, data, original_count):
    header = header.replace(b"element vertex %d\n" % original_count, b"element vertex %d\n" % len(data))
    with open(path, "wb") as f:
        f.write(header + data.astype("<f4").tobytes())


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("model")
    parser.add_argument("out")
    parser.add_argument("ops")
    parser.add_argument("--cameras")
    parser.add_argument("--cull", type=float)
    args = parser.parse_args()
    header, props, data = read_ply(args.model)
    count = len(data)
    ops = [op for op in args.ops.split(",") if op]
    dc = [props.index(f"f_dc_{i}") for i in range(3)]
    for op in ops:
        if op == "sh0":
            data[:, [i for i, p in enumerate(props) if p.startswith("f_rest_")]] = 0
        elif op == "clamp01":
            data[:, dc] = (np.clip(data[:, dc] * SH_C0 + 0.5, 0, 1) - 0.5) / SH_C0
        else:
            parser.error(f"unknown op {op}")
    os.makedirs(args.out, exist_ok=True)
    if args.cull is None:
        write_ply(os.path.join(args.out, "model.ply"), header, data, count)
        return
    xyz = data[:, [props.index(c) for c in "xyz"]].astype(np.float64)
    for cam in json.load(open(args.cameras)):
        # cameras.json: rotation = camera-to-world rows, position = centre; COLMAP camera axes.
        local = (xyz - np.array(cam["position"])) @ np.array(cam["rotation"])
        z = local[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = 2 * (cam["fx"] * local[:, 0] / z + cam["cx"]) / cam["width"] - 1
            v = 2 * (cam["fy"] * local[:, 1] / z + cam["cy"]) / cam["height"] - 1
        keep = (z > 0.01) & (np.abs(u) <= args.cull) & (np.abs(v) <= args.cull)
        print(f"{cam['img_name']}: {keep.sum()} of {count} splats kept ({(z > 0.01).sum()} in front)")
        write_ply(os.path.join(args.out, cam["img_name"] + ".ply"), header, data[keep], count)


if __name__ == "__main__":
    main()
