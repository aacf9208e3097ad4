#!/usr/bin/env python3
"""Times gsplat's rasterization (forward + backward) on the scene raster_benchmark wrote
(`raster_benchmark --scenes 1000 --write_scene DIR`: DIR/scene_1m.ply, an Inria PLY, and
DIR/camera_1m.json), the work watergs' device-resident figure times: one 1920x1080 frame of
1M Gaussians, SH degree 3, black background, a random image gradient. Run by the `gsplat` stage
of scripts/gpu_check.sh with the bundled gsplat on PYTHONPATH; PyTorch with CUDA is the device's.

  python3 scripts/gsplat_timing.py DIR [--repeats N]
"""
import json
import statistics
import sys

import torch


def read_ply(path):
    """Float properties of a binary little-endian PLY, as {name: tensor [N]}."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        if "format binary_little_endian 1.0" not in header:
            sys.exit(f"gsplat_timing: {path}: not a binary little-endian PLY")
        count = int(next(l for l in header if l.startswith("element vertex")).split()[2])
        props = [l.split() for l in header if l.startswith("property")]
        if any(p[1] != "float" for p in props):
            sys.exit(f"gsplat_timing: {path}: expected float properties only")
        names = [p[2] for p in props]
        data = torch.frombuffer(bytearray(f.read(4 * count * len(names))), dtype=torch.float32)
    data = data.reshape(count, len(names))
    return {name: data[:, i] for i, name in enumerate(names)}


def main():
    scene = sys.argv[1]
    repeats = int(sys.argv[sys.argv.index("--repeats") + 1]) if "--repeats" in sys.argv else 9
    import gsplat  # the bundled one (PYTHONPATH)

    p = read_ply(f"{scene}/scene_1m.ply")
    cam = json.load(open(f"{scene}/camera_1m.json"))
    dev = torch.device("cuda")
    stack = lambda keys: torch.stack([p[k] for k in keys], dim=1).to(dev)
    means = stack(["x", "y", "z"]).requires_grad_()
    quats = stack([f"rot_{i}" for i in range(4)]).requires_grad_()  # w, x, y, z
    log_scales = stack([f"scale_{i}" for i in range(3)]).requires_grad_()
    opacity_logits = p["opacity"].to(dev).requires_grad_()
    rest = sorted((k for k in p if k.startswith("f_rest_")), key=lambda k: int(k[7:]))
    # Inria's f_rest is channel-major (3 x 15); gsplat takes [N, K, 3].
    sh_rest = stack(rest).reshape(-1, 3, len(rest) // 3).transpose(1, 2)
    sh = torch.cat([stack(["f_dc_0", "f_dc_1", "f_dc_2"])[:, None, :], sh_rest], 1)
    sh = sh.contiguous().requires_grad_()
    sh_degree = round((sh.shape[1]) ** 0.5) - 1  # (degree + 1)^2 coefficients
    viewmat = torch.tensor(cam["viewmat"], dtype=torch.float32, device=dev).reshape(1, 4, 4)
    K = torch.tensor([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1]],
                     dtype=torch.float32, device=dev)[None]
    w, h = cam["width"], cam["height"]
    grad_image = (torch.rand(1, h, w, 3, device=dev) - 0.5) * 2e-5

    def forward():
        image, _, _ = gsplat.rasterization(
            means, quats, torch.exp(log_scales), torch.sigmoid(opacity_logits), sh, viewmat, K,
            w, h, near_plane=0.01, far_plane=1000.0, sh_degree=sh_degree)
        return image

    for _ in range(2):  # warm-up: the JIT build's first load, allocations
        forward().backward(grad_image)
    times = {"forward": [], "backward": [], "both": []}
    for _ in range(repeats):
        e = [torch.cuda.Event(enable_timing=True) for _ in range(3)]
        e[0].record()
        image = forward()
        e[1].record()
        image.backward(grad_image)
        e[2].record()
        torch.cuda.synchronize()
        f, b = e[0].elapsed_time(e[1]), e[1].elapsed_time(e[2])
        times["forward"].append(f), times["backward"].append(b), times["both"].append(f + b)
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"gsplat {gsplat.__version__} (torch {torch.__version__}, {torch.cuda.get_device_name()}): "
          f"{means.shape[0]} Gaussians {w}x{h} sh{sh_degree}: forward {med['forward']:.2f} ms, backward "
          f"{med['backward']:.2f} ms, fwd+bwd {med['both']:.2f} ms (CUDA events, median of "
          f"{repeats}); mean pixel {image.mean().item():.4f}")


if __name__ == "__main__":
    main()
