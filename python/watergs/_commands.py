"""The CLI's commands as Python functions.

Each function runs the command in-process (``_watergs.run_command``, the
code ``watergs <command>`` runs) with its keyword arguments written as
``--name=value`` words, so that option names, defaults, checks and error
messages have one source: the command's own option parser. The result
object is read back from the files the command wrote (the same files a CLI
user gets), and numpy arrays are made only here, on demand.
"""

import collections
import json
import math
import numbers
import os
import shutil
import sys
import tempfile

from . import _watergs
from ._watergs import Error, Model

Progress = collections.namedtuple(
    "Progress", ["label", "done", "total", "status", "finished"])
Progress.__doc__ = """One step of a command's progress line: `done` of `total`
steps of `label` ("train", "embed", "render"), the line's figures in
`status` ("loss 0.031  41234 Gaussians"); `finished` at the last call."""


def _numpy():
    try:
        import numpy
    except ImportError as e:
        raise ImportError(
            "watergs: this result holds arrays, which need numpy "
            "(apt-get install python3-numpy)") from e
    return numpy


def _value_text(command, name, value):
    """One option value as the command line's text; TypeError for a type
    the CLI cannot take, Error for a non-finite number."""
    if isinstance(value, bool):
        raise TypeError(f"{command}(): {name} lists {value!r}: a list holds "
                        "numbers or text")
    if isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        path = os.fspath(value)
        if isinstance(path, str):
            return path
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        number = float(value)
        if not math.isfinite(number):
            raise Error(f"--{name}: {number} is not a finite number")
        return repr(number)
    raise TypeError(
        f"{command}(): {name} must be a str, path, number or bool (or a "
        f"list of them), not {type(value).__name__}")


def _words(command, options):
    """Keyword arguments -> ["--name=value", "--flag", ...]. None leaves the
    option at its default, True/False write --name=1/--name=0 (every boolean
    takes them, so False turns off one that defaults on), a list or tuple
    (or numpy array) is written comma-separated ("7000,30000", "1,1,1")."""
    words = []
    for name, value in options.items():
        # numpy arrays and scalars (numpy.bool_ included) as Python values.
        if hasattr(value, "tolist") and not isinstance(value, str):
            value = value.tolist()
        if value is None:
            continue
        if isinstance(value, bool):
            words.append(f"--{name}={int(value)}")
            continue
        if isinstance(value, (list, tuple)):
            text = ",".join(_value_text(command, name, v) for v in value)
        else:
            text = _value_text(command, name, value)
        words.append(f"--{name}={text}")
    return words


def _callback(progress):
    if progress is None:
        return None
    if not callable(progress):
        raise TypeError(f"progress must be callable, not "
                        f"{type(progress).__name__}")
    return lambda *fields: progress(Progress(*fields))


def run(command, *, progress=None, quiet=False, **options):
    """Runs any CLI command in this process: ``run("model_info",
    sparse_path="scene/sparse/0")`` is ``watergs model_info --sparse_path
    scene/sparse/0``. Prints what the CLI prints (quiet=True: nothing);
    `progress(watergs.Progress)` is called at each step of its progress
    line. Raises watergs.Error with the CLI's one-line message for bad
    input; Ctrl-C raises KeyboardInterrupt after the command has stopped."""
    if not isinstance(command, str):
        raise TypeError(f"command must be a str, not {type(command).__name__}")
    if "help" in options or "h" in options:
        raise TypeError(f"{command}(): use watergs.help({command!r}) for "
                        "the options")
    words = _words(command, options)
    # Python's buffered text first, then the command's.
    for stream in (sys.stdout, sys.stderr):
        if stream is not None:
            stream.flush()
    code = _watergs.run_command(command, words, _callback(progress),
                                bool(quiet))
    if code != 0:
        raise Error(f"watergs {command} exited with code {code}")


def help(command):  # noqa: A001 (watergs.help mirrors `watergs help CMD`)
    """The options of CLI command `command`, as `watergs help <command>`
    prints them: these are the keyword arguments of the function."""
    return _watergs.command_help(command)


def _path(name, value):
    if isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        path = os.fspath(value)
        if isinstance(path, str):
            return path
    raise TypeError(f"{name} must be a path (str or os.PathLike), not "
                    f"{type(value).__name__}")


def _read_json(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


class _Result:
    """Fields as attributes; repr lists the scalar ones."""

    def __repr__(self):
        shown = []
        for key, value in vars(self).items():
            if isinstance(value, (str, int, float, bool)) or value is None:
                shown.append(f"{key}={value!r}")
        return f"{type(self).__name__}({', '.join(shown)})"


class TrainResult(_Result):
    """A finished `train` run. output_path: the run's folder; ply_path: its
    point_cloud.ply; report: report.json as a dict; psnr, ssim, l1 on the
    held-out views (on the training views without split="train");
    num_gaussians, iterations, seconds."""

    def __init__(self, output_path):
        self.output_path = output_path
        self.ply_path = os.path.join(output_path, "point_cloud.ply")
        self.report = _read_json(os.path.join(output_path, "report.json"))
        self.psnr = self.report["psnr"]
        self.ssim = self.report["ssim"]
        self.l1 = self.report["l1"]
        self.num_gaussians = self.report["num_gaussians"]
        self.iterations = self.report["iterations"]
        self.seconds = self.report["train_seconds"]

    def load_model(self):
        """The trained model (watergs.Model)."""
        return Model.load(self.ply_path)


def train(workspace_path, output_path, *, progress=None, quiet=False,
          **options):
    """Trains a 3DGS model on a COLMAP workspace: ``watergs train``.
    Writes point_cloud.ply, cameras.json, train_log.jsonl and report.json
    into `output_path`; returns a TrainResult. Keyword arguments: the CLI's
    options (below)."""
    output_path = _path("output_path", output_path)
    run("train", progress=progress, quiet=quiet,
        workspace_path=_path("workspace_path", workspace_path),
        output_path=output_path, **options)
    return TrainResult(output_path)


class EmbedResult(_Result):
    """A watermarked model. output_path: its PLY (in the input's layout)."""

    def __init__(self, output_path):
        self.output_path = output_path

    def load_model(self):
        """The watermarked model (watergs.Model)."""
        return Model.load(self.output_path)


def embed(input_path, workspace_path, decoder, message, output_path, *,
          progress=None, quiet=False, **options):
    """Embeds a WATER-GS watermark: ``watergs embed``. Fine-tunes the model
    at `input_path` on its workspace so that `decoder` reads `message` from
    its renders, and writes the result to `output_path`; returns an
    EmbedResult. Keyword arguments: the CLI's options (below)."""
    output_path = _path("output_path", output_path)
    run("embed", progress=progress, quiet=quiet,
        input_path=_path("input_path", input_path),
        workspace_path=_path("workspace_path", workspace_path),
        decoder=_path("decoder", decoder), message=message,
        output_path=output_path, **options)
    return EmbedResult(output_path)


def pipeline(image_path, decoder, message, output_path, *, progress=None,
             quiet=False, **options):
    """From a folder of photos to a watermarked model and its ownership
    report: ``watergs pipeline`` (reconstruct, train, embed --report). Writes
    OUTPUT/workspace, OUTPUT/train, OUTPUT/watermarked.ply and
    OUTPUT/report.html; a second call keeps the stages done. Returns an
    EmbedResult for OUTPUT/watermarked.ply. Keyword arguments: the CLI's
    options (below)."""
    output_path = _path("output_path", output_path)
    run("pipeline", progress=progress, quiet=quiet,
        image_path=_path("image_path", image_path),
        decoder=_path("decoder", decoder), message=message,
        output_path=output_path, **options)
    return EmbedResult(os.path.join(output_path, "watermarked.ply"))


class ExtractResult(_Result):
    """What `extract` read, and its verdict on the claimed message.

    recovered_bits: numpy uint8 array (0/1), the message read from the
    logits averaged over the views; recovered_hex. With a claimed message:
    expected_bits, bit_errors, ber, p_value (the chance of this many
    matching bits from an unmarked model), verdict ("watermark present",
    "watermark absent" or "inconclusive"), present (verdict is "watermark
    present"), false_positive_rate; otherwise these are None. Per view:
    view_names, view_ber (numpy float64, each view decoded alone; None
    without a message). mean_logits: numpy float32. report: the --json
    output as a dict. owner: with raw_path=RAW, the owner's reading (each
    view's logits minus the raw model's at the same viewpoint) as an
    ExtractResult of its own; None without raw_path.
    """

    def __init__(self, report):
        np = _numpy()
        self.report = report
        self.num_bits = report["num_bits"]
        self.num_views = report["num_views"]
        self.recovered_hex = report["recovered_hex"]
        self.recovered_bits = np.array(
            [int(b) for b in report["recovered_bits"]], dtype=np.uint8)
        self.mean_logits = np.array(report["mean_logits"], dtype=np.float32)
        self.view_names = [v["name"] for v in report["views"]]
        claimed = "expected_bits" in report
        self.expected_bits = np.array(
            [int(b) for b in report["expected_bits"]],
            dtype=np.uint8) if claimed else None
        self.bit_errors = report.get("bit_errors")
        self.ber = report.get("ber")
        self.p_value = report.get("p_value")
        self.verdict = report.get("verdict")
        self.present = self.verdict == "watermark present" if claimed else None
        self.false_positive_rate = report.get("false_positive_rate")
        self.view_ber = np.array(
            [v["bit_errors"] / self.num_bits for v in report["views"]],
            dtype=np.float64) if claimed else None
        self.owner = ExtractResult(report["owner"]) if "owner" in report \
            else None


def extract(input_path, workspace_path, decoder, message=None, *,
            progress=None, quiet=False, **options):
    """Reads the WATER-GS watermark of a model from its renders and tests it
    against the claimed `message`: ``watergs extract``. Returns an
    ExtractResult (a verdict is a result, not an error). json=PATH also
    keeps the JSON file. Keyword arguments: the CLI's options (below)."""
    json_path = options.pop("json", None)
    folder = None
    if json_path is None:
        folder = tempfile.mkdtemp(prefix="watergs_extract_")
        json_path = os.path.join(folder, "extract.json")
    try:
        run("extract", progress=progress, quiet=quiet,
            input_path=_path("input_path", input_path),
            workspace_path=_path("workspace_path", workspace_path),
            decoder=_path("decoder", decoder), message=message,
            json=_path("json", json_path), **options)
        return ExtractResult(_read_json(json_path))
    finally:
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)


class AttackResult(_Result):
    """An attacked model. output_path: its PLY; transform: the similarity
    the scene was moved by ("similarity:..."), or None; transform_path: the
    file holding it, for extract(scene_transform=...)."""

    def __init__(self, output_path, moved):
        self.output_path = output_path
        self.transform_path = None
        self.transform = None
        if moved:
            self.transform_path = output_path + ".transform.txt"
            with open(self.transform_path, encoding="utf-8") as f:
                self.transform = f.read().strip()

    def load_model(self):
        """The attacked model (watergs.Model)."""
        return Model.load(self.output_path)


def attack(input_path, attack, output_path, *, quiet=False, **options):
    """Attacks a PLY (3D distortions, SH truncation, quantisation, a
    similarity transform, ...): ``watergs attack``. `attack` is the CLI's
    comma-separated list ("gn:0.01,dropout:0.1") or a Python list of them.
    Returns an AttackResult. Keyword arguments: the CLI's options (below)."""
    output_path = _path("output_path", output_path)
    # A transform file left by an earlier attack on this output is not this
    # attack's: only a new or rewritten file counts.
    before = _stat(output_path + ".transform.txt")
    run("attack", quiet=quiet, input_path=_path("input_path", input_path),
        attack=attack, output_path=output_path, **options)
    after = _stat(output_path + ".transform.txt")
    return AttackResult(output_path, after is not None and after != before)


def _stat(path):
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_ino, st.st_mtime_ns, st.st_size)


class RenderResult(_Result):
    """Renders of a model from a workspace's cameras. names: the views;
    images: one numpy uint8 array height x width x 3 per view (the PNGs
    `watergs render` writes); psnr, ssim: per view against the workspace's
    images (None without its image folder); mean_psnr, mean_ssim;
    output_path: the PNGs' folder (None when it was temporary); report:
    render_report.json as a dict."""

    def __init__(self, folder, output_path):
        self.report = _read_json(os.path.join(folder, "render_report.json"))
        self.output_path = output_path
        self.split = self.report["split"]
        views = self.report["views"]
        self.names = [v["name"] for v in views]
        # As the CLI names the PNGs: Inria's basename up to its first dot.
        self.images = [
            _watergs.read_image_u8(
                os.path.join(folder,
                             os.path.basename(n).split(".")[0] + ".png"))
            for n in self.names
        ]
        truth = self.report["psnr"] is not None
        self.psnr = [v["psnr"] for v in views] if truth else None
        self.ssim = [v["ssim"] for v in views] if truth else None
        self.mean_psnr = self.report["psnr"]
        self.mean_ssim = self.report["ssim"]


def render(input_path, workspace_path, output_path=None, *, progress=None,
           quiet=False, **options):
    """Renders a model from a workspace's cameras (split="test" by default,
    "train" or "all") and scores the renders against its images:
    ``watergs render``. The PNGs go to `output_path`, or to a temporary
    folder removed afterwards when it is None. Returns a RenderResult.
    Keyword arguments: the CLI's options (below)."""
    folder = output_path
    if folder is None:
        _numpy()  # before the work, not after
        folder = tempfile.mkdtemp(prefix="watergs_render_")
    try:
        run("render", progress=progress, quiet=quiet,
            input_path=_path("input_path", input_path),
            workspace_path=_path("workspace_path", workspace_path),
            output_path=_path("output_path", folder), **options)
        return RenderResult(folder, output_path)
    finally:
        if output_path is None:
            shutil.rmtree(folder, ignore_errors=True)


def _add_cli_help():
    """Appends each command's CLI options to its function's docstring."""
    for function in (train, embed, extract, attack, render, pipeline):
        try:
            text = _watergs.command_help(function.__name__)
        except Exception:  # a docstring is not worth a failed import
            continue
        function.__doc__ = (function.__doc__ or "") + "\n\n" + text


_add_cli_help()
