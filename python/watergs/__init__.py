"""watergs from Python: 3D Gaussian Splatting on COLMAP workspaces and
WATER-GS watermarks (train, embed, extract, attack, render).

The pipeline steps take the CLI's options as keyword arguments (same names,
defaults and checks: the CLI's own code parses them; ``watergs.help("embed")``
lists them) and return result objects with numpy arrays::

    import watergs
    trained = watergs.train("scene", "out/train", downscale=2, iterations=2000)
    marked = watergs.embed(trained.ply_path, "scene", "decoder_48_residual_pool2.bin",
                           "text:WGS-26", "out/wm.ply", downscale=2)
    result = watergs.extract(marked.output_path, "scene", "decoder_48_residual_pool2.bin",
                             message="text:WGS-26", downscale=2)
    print(result.verdict, result.p_value, result.view_ber)

Models, workspaces and cameras are objects too: ``watergs.Model.load(ply)``,
``watergs.Workspace("scene")``, ``model.render(workspace.camera(0))`` (an
HxWx3 float32 array).

Errors: bad input (a missing file, a malformed option, NaN in an array)
raises ``watergs.Error`` (a RuntimeError) with the CLI's one-line message; a
value of the wrong Python type raises TypeError. Ctrl-C stops a running
command (KeyboardInterrupt). numpy is needed only by the calls that take or
return arrays. docs/python.md has the details.
"""

from ._watergs import Camera, Error, Model, Workspace, __commit__, __version__
from ._watergs import cuda_available as _cuda_available
from ._commands import (
    AttackResult,
    EmbedResult,
    ExtractResult,
    Progress,
    RenderResult,
    TrainResult,
    attack,
    embed,
    extract,
    help,
    pipeline,
    render,
    run,
    train,
)


def cuda_available():
    """(True, "") when this build has the CUDA backend and a GPU is visible,
    else (False, why); --device auto then picks the CPU."""
    return _cuda_available()


__all__ = [
    "AttackResult",
    "Camera",
    "EmbedResult",
    "Error",
    "ExtractResult",
    "Model",
    "Progress",
    "RenderResult",
    "TrainResult",
    "Workspace",
    "attack",
    "cuda_available",
    "embed",
    "extract",
    "pipeline",
    "render",
    "run",
    "train",
]
