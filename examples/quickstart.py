#!/usr/bin/env python3
"""watergs from Python in one minute: train a small 3DGS model of the demo
scene, embed a 48-bit WATER-GS watermark with the shipped decoder, and check
both models with extract: the watermarked one as its owner reads it (minus
the raw model's renders, which the owner keeps).
    python3 examples/quickstart.py [OUTPUT_DIR]      (default: quickstart_out)
"""
import pathlib
import sys

import watergs

root = pathlib.Path(__file__).resolve().parent.parent
scene = root / "datasets_scripts" / "demo_scene"
decoder = root / "watermark" / "models" / "decoder_48_residual_pool2.bin"
out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "quickstart_out")
message = "text:WGS-26"  # 6 characters: the decoder's 48 bits
common = dict(downscale=4, quiet=True)  # 120x90 pixels

trained = watergs.train(scene, out / "train", iterations=200, overwrite=True,
                        **common)
print(f"trained: {trained.num_gaussians} Gaussians, PSNR {trained.psnr:.1f} dB")
marked = watergs.embed(trained.ply_path, scene, decoder, message,
                       out / "wm.ply", iterations=300, **common)
# The unmarked model read on its own; the watermarked one as its owner reads
# it: each view minus the raw model's render (extract's raw_path).
unmarked = watergs.extract(trained.ply_path, scene, decoder, message=message,
                           **common)
print(f"unmarked: BER {unmarked.ber:.1%}, p-value {unmarked.p_value:.1e}, "
      f"{unmarked.verdict}")
r = watergs.extract(marked.output_path, scene, decoder, message=message,
                    raw_path=trained.ply_path, **common).owner
print(f"watermarked: BER {r.ber:.1%}, p-value {r.p_value:.1e}, {r.verdict}")
