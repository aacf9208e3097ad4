#!/usr/bin/env python3
"""PSNR of viewer screenshots against watergs' renders of the same cameras.

  python3 compare.py REFERENCE_DIR SHOTS_DIR [--json OUT] [--shift N] [--overlay DIR]

For every REFERENCE_DIR/<name>.png with a SHOTS_DIR/<name>.png beside it: the PSNR over the 8-bit
RGB pixels (peak 255), the mean difference per channel (a colour offset), and, with --shift N,
the best PSNR over whole-pixel shifts of the screenshot within +-N pixels (compared on the
overlap): a camera convention off by a flip or a half-frame shows as a low PSNR that no small shift
repairs, a pixel-centre offset as a best shift away from (0, 0). --overlay writes, per image, the
reference's edges in red over the screenshot's in green (yellow where they agree). PNGs are read
with zlib alone (8-bit, non-interlaced RGB or RGBA: what OpenCV and Chromium write), so numpy is
the only dependency. Prints one line per image and the mean; exit 1 when no pair is found.
"""
import argparse
import json
import os
import struct
import sys
import zlib

import numpy as np


def read_png(path):
    """8-bit non-interlaced RGB(A)/grey PNG -> uint8 array (H, W, 3)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, header = 8, [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(colour)
    if depth != 8 or interlace != 0 or channels is None:
        raise ValueError(f"{path}: only 8-bit non-interlaced grey/RGB(A) PNGs")
    raw = zlib.decompress(b"".join(idat))
    stride = width * channels
    out = bytearray(height * stride)
    prev = bytearray(stride)
    for y in range(height):  # PNG's filters, undone in plain Python ints (fast enough at these sizes)
        kind = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        if kind == 1:
            for x in range(channels, stride):
                line[x] = (line[x] + line[x - channels]) & 255
        elif kind == 2:
            line = bytearray((np.frombuffer(line, np.uint8) + np.frombuffer(prev, np.uint8)).tobytes())
        elif kind == 3:
            for x in range(stride):
                left = line[x - channels] if x >= channels else 0
                line[x] = (line[x] + ((left + prev[x]) >> 1)) & 255
        elif kind == 4:
            for x in range(stride):
                a = line[x - channels] if x >= channels else 0
                b = prev[x]
                c = prev[x - channels] if x >= channels else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else (b if pb <= pc else c))) & 255
        elif kind != 0:
            raise ValueError(f"{path}: bad filter {kind}")
        out[y * stride:(y + 1) * stride] = line
        prev = line
    out = np.frombuffer(bytes(out), np.uint8)
    image = out.reshape(height, width, channels)
    if channels in (1, 2):
        image = np.repeat(image[:, :, :1], 3, axis=2)
    return image[:, :, :3]


def write_png(path, image):
    """uint8 (H, W, 3) -> PNG (filter 0)."""
    height, width, _ = image.shape
    raw = b"".join(b"\x00" + image[y].tobytes() for y in range(height))

    def chunk(kind, body):
        return (struct.pack(">I", len(body)) + kind + body +
                struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def best_shift(reference, shot, radius):
    """(psnr, dx, dy) of the whole-pixel shift of `shot` that matches `reference` best."""
    best = (psnr(reference, shot), 0, 0)
    h, w, _ = reference.shape
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dx == 0 and dy == 0:
                continue
            ref = reference[max(0, dy):h + min(0, dy), max(0, dx):w + min(0, dx)]
            sh = shot[max(0, -dy):h + min(0, -dy), max(0, -dx):w + min(0, -dx)]
            value = psnr(ref, sh)
            if value > best[0]:
                best = (value, dx, dy)
    return best


def edges(image):
    grey = image.astype(np.float64).mean(axis=2)
    gx = np.zeros_like(grey)
    gy = np.zeros_like(grey)
    gx[:, 1:-1] = grey[:, 2:] - grey[:, :-2]
    gy[1:-1, :] = grey[2:, :] - grey[:-2, :]
    magnitude = np.hypot(gx, gy)
    return magnitude > np.percentile(magnitude, 85)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("reference")
    parser.add_argument("shots")
    parser.add_argument("--json")
    parser.add_argument("--shift", type=int, default=0)
    parser.add_argument("--overlay")
    args = parser.parse_args()
    rows = []
    for name in sorted(os.listdir(args.reference)):
        if not name.endswith(".png") or not os.path.exists(os.path.join(args.shots, name)):
            continue
        reference = read_png(os.path.join(args.reference, name))
        shot = read_png(os.path.join(args.shots, name))
        if shot.shape != reference.shape:
            print(f"{name}: screenshot {shot.shape[1]}x{shot.shape[0]} but render "
                  f"{reference.shape[1]}x{reference.shape[0]}", file=sys.stderr)
            sys.exit(1)
        diff = shot.astype(np.float64) - reference.astype(np.float64)
        row = {"name": name[:-4], "psnr": psnr(reference, shot),
               "mean_diff_rgb": [float(v) for v in diff.reshape(-1, 3).mean(axis=0)],
               "mean_abs_diff": float(np.abs(diff).mean())}
        if args.shift > 0:
            value, dx, dy = best_shift(reference, shot, args.shift)
            row.update(best_shift_psnr=value, best_shift=[dx, dy])
        if args.overlay:
            os.makedirs(args.overlay, exist_ok=True)
            overlay = np.zeros_like(reference)
            overlay[:, :, 0] = edges(reference) * 255
            overlay[:, :, 1] = edges(shot) * 255
            write_png(os.path.join(args.overlay, name), overlay)
        rows.append(row)
        shift = (f"  best shift ({row['best_shift'][0]:+d}, {row['best_shift'][1]:+d}) "
                 f"{row['best_shift_psnr']:.2f} dB" if args.shift > 0 else "")
        print(f"{row['name']:<16} PSNR {row['psnr']:6.2f} dB  mean diff RGB "
              f"{' '.join(f'{v:+.2f}' for v in row['mean_diff_rgb'])}{shift}")
    if not rows:
        print(f"compare.py: no PNG in {args.reference} has a screenshot in {args.shots}", file=sys.stderr)
        sys.exit(1)
    mean = float(np.mean([r["psnr"] for r in rows]))
    print(f"mean PSNR {mean:.2f} dB over {len(rows)} images")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"reference": args.reference, "shots": args.shots, "mean_psnr": mean, "images": rows}, f,
                      indent=2)
            f.write("\n")


if __name__ == "__main__":
    main()
