"""The README's figures, each traced to the committed file under results/ that backs it (the paper's
own figures, set beside ours, to its LaTeX source: PAPER).

One manifest, CLAIMS below: each entry is a README phrase with a `{}` where a measured figure
stands, the files it comes from, how each figure is read from them, and (optionally) a tolerance.
`check(readme_text, root)` reads every phrase in the README, reads the figures from the files and
returns one line per mismatch: a figure unlike its file (beyond the README's rounding: half a unit
of the last digit it prints, unless the entry says otherwise), a phrase no longer in the README, a
file that is gone, or a file not named beside its figure (in the same table row, or in the same
paragraph or the one before it). check_claims.py --readme runs it. Python standard library only.

Adding a figure to the README: add an entry here naming its file; the figure then cannot drift
from the file, nor the file from the README, without this check saying so. `uncovered` (check_claims.py
--readme README.md --uncovered) lists the numbers no entry covers, by the rule stated above SETTINGS.
"""
import json
import os
import math
import re
import statistics

NUMBER = r"(-?\d[\d,]*(?:\.\d+)?)"


# ---- Sources: the files a figure is read from, and how (values(root) -> list of figures). ------

class Source:
    def __init__(self, files, read):
        self.files = files
        self.read = read  # root -> list of floats

    def values(self, root):
        return self.read(root)


def _text(root, path):
    full = os.path.join(root, path)
    try:
        with open(full, encoding="utf-8") as f:
            return f.read()
    except OSError as e:
        raise LookupError(f"{path}: {e.strerror}") from None


def _numbers(text):
    return [float(n.replace(",", "")) for n in re.findall(NUMBER, text)]


def grep(path, pattern, flags=re.M):
    """The numbers of every group of the first match of pattern in the file."""
    def read(root):
        m = re.search(pattern, _text(root, path), flags)
        if not m:
            raise LookupError(f"{path}: no line matches /{pattern}/")
        return [float(g.replace(",", "")) for g in m.groups()]
    return Source([path], read)



# A figure of one screenshot set (gs3d_wm, playcanvas_raw, ...) in a ber.tsv that
# results/viewers/reference_conventions/measure.sh writes, read after "SETTING\tSET\t": screenshots
# registered, the mean BER, how many read "present" or "absent" alone, bits wrong of the set together.
_SHOT_FIELDS = {
    "registered": r"(\d+) of \d+",
    "mean": r"(?:[^\t]*\t){2}([\d.]+)%",
    "present": r"(?:[^\t]*\t){3}(\d+) /",
    "absent": r"(?:[^\t]*\t){3}\d+ / \d+ / (\d+)",
    "together": r"(?:[^\t]*\t){4}\w+ \((\d+) of 48\)",
}


def curve(label, conventions):
    """A file's mean single-view BER under one renderer's conventions in the simulated curve."""
    return grep(VC33 + "curve.tsv", rf"^{re.escape(label)}\t{conventions}\tsingle views \(\d+\): BER mean ([\d.]+)%")


def shots(tsv, screenshots, field, setting="auto"):
    return grep(tsv, rf"^{setting}\t{screenshots}\t" + _SHOT_FIELDS[field])


def cell(path, keys, column, index=0):
    """The index-th number in a Markdown table cell: the row whose first cells are keys, the column
    whose header starts with column (the header row of the table that row is in)."""
    keys = (keys,) if isinstance(keys, str) else tuple(keys)

    def read(root):
        header = None
        for line in _text(root, path).splitlines():
            if not line.startswith("|"):
                header = None
                continue
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if header is None:
                header = cells
                continue
            columns = [i for i, h in enumerate(header) if h.strip("*").startswith(column)]
            if tuple(cells[:len(keys)]) != keys or not columns:
                continue
            found = _numbers(cells[columns[0]])
            if len(found) <= index:
                raise LookupError(f"{path}: row {' | '.join(keys)}, column '{column}' has no number {index + 1}")
            return [found[index]]
        raise LookupError(f"{path}: no table row {' | '.join(keys)} with a column '{column}'")
    return Source([path], read)


def json_at(path, *keys):
    """Numbers in a JSON file, by keys and list indices; "*" takes the rest of the keys in every
    element of a list ("owner", "views", "*", "bit_errors": each view's bit errors); "?k=v&k2=v2"
    the first element of a list whose fields have those values."""
    def walk(value, keys):
        if not keys:
            return value if isinstance(value, list) else [value]
        if keys[0] == "*":
            return [v for element in value for v in walk(element, keys[1:])]
        if isinstance(keys[0], str) and keys[0].startswith("?"):
            wanted = dict(pair.split("=", 1) for pair in keys[0][1:].split("&"))
            value = next(e for e in value if all(str(e.get(k)) == v for k, v in wanted.items()))
            return walk(value, keys[1:])
        return walk(value[keys[0]], keys[1:])

    def read(root):
        try:
            return [float(v) for v in walk(json.loads(_text(root, path)), list(keys))]
        except (ValueError, KeyError, IndexError, TypeError, StopIteration):
            raise LookupError(f"{path}: no value at {'/'.join(map(str, keys))}") from None
    return Source([path], read)


def count(path, pattern):
    """How many lines of the file match pattern."""
    def read(root):
        return [float(len(re.findall(pattern, _text(root, path), re.M)))]
    return Source([path], read)


def count_where(path, keys, value):
    """How many of the numbers at keys in a JSON file (json_at) equal value."""
    return combine(lambda v: sum(x == value for x in v), json_at(path, *keys))


def combine(function, *sources):
    """function(all the sources' figures, in order) -> one figure or a list of them."""
    def read(root):
        values = [v for s in sources for v in s.values(root)]
        result = function(values)
        return list(result) if isinstance(result, (list, tuple)) else [result]
    return Source([f for s in sources for f in s.files], read)


def lowest(*sources):
    return combine(min, *sources)


def highest(*sources):
    return combine(max, *sources)


def span(*sources):
    """Two figures: the lowest and the highest."""
    return combine(lambda v: (min(v), max(v)), *sources)


def mean(*sources):
    return combine(statistics.mean, *sources)


def difference(a, b):
    """a - b."""
    return combine(lambda v: v[0] - v[1], a, b)


def scaled(factor, source):
    return combine(lambda v: [x * factor for x in v], source)



class Claim:
    def __init__(self, phrase, *sources, tol=None, name=None):
        self.phrase = phrase  # README text, `{}` where a figure stands
        self.sources = sources
        self.tol = tol
        self.name = name

    def pattern(self):
        parts = self.phrase.split("{}")
        return re.compile(NUMBER.join(re.escape(p).replace("\\ ", r"\s+") for p in parts))

    def files(self):
        return list(dict.fromkeys(f for s in self.sources for f in s.files))


class Lines:
    """A README fenced block whose every line must be a line of the file (after `normalize`)."""

    def __init__(self, first_line, path, normalize=lambda line: line):
        self.first_line = first_line
        self.path = path
        self.normalize = normalize
        self.name = None

    def files(self):
        return [self.path]


# ---- The manifest. -----------------------------------------------------------------------------

DRAWS = "results/real_llff/horns_252x189_draws/tables.md"
DEMO = "results/demo/run_demo.log"
DEMO_S29 = "results/demo/session29_run_demo.log"  # the previous default's run (--target_psnr 0)
DEMO_HELD = "results/demo/extract_wm_heldout.json"
DEMO_FREE = "results/demo/extract_wm_free.json"
OPENSPLAT = "results/third_party/opensplat_demo/summary.txt"
GPU = "results/gpu/h200-2026-11-26/demo.txt"
FAST = "results/testing/fast_tier.txt"
DETECT = "results/detect_probe/demo_default/"
NULL = "results/owner_reading/owner_null.md"
BLIND = "results/blind_designs/results.txt"
# The designs' raw model (blind_decoder_designs.sh trains it as run_demo.sh does): its held-out PSNR.
BLIND_RAW_PSNR = grep("results/blind_designs/raw_train.log", r"held-out views \(6\): PSNR ([\d.]+) dB")
LEGO = "results/nerf_synthetic_lego/tables.md"
BOTH = "results/reading_both/results.txt"
BOTH_R2P2 = ("r2p2_both_w0.5_m0", "r2p2_both_w0.5_m0_s1", "r2p2_both_w0.5_m0_s2")
RECORDING = "results/viewers/recording/recording.tsv"
RECORDING_T38 = "results/viewers/default_t38/recording/recording.tsv"
VIEWER_BER = "results/viewers/reference_conventions/ber.tsv"
DETECT_COST = "results/viewers/detect_cost/"
VIEWER_BOTH = "results/viewers/default_both/ber.tsv"
VIEWER_T38J = "results/viewers/default_t38/jpeg_layer/"
# The same screenshots read with the viewers' small-splat rules emulated (session 32).
VC = "results/viewers/viewer_conventions/"
# Read again with the viewers' 8-bit canvas and storage emulated (session 33): the README's figures.
VC33 = VC + "session33/"
JLS = "results/viewers/jpeg_layer_strength/"  # session 38: the layer's strength, the first default's decoder
FERN_T38_S31 = "results/viewers/default_t38/fern_t38/"  # before
F2B_DIR = "results/real_llff/fern_252x189_both/"
H2B_DIR = "results/real_llff/horns_252x189_both/"
BOTH_SEEDS = ("both_seed0", "both_seed1", "both_seed2")
T38 = ("both_seed0_t38", "both_seed1_t38", "both_seed2_t38")
BUDGET_DEMO = "results/blind_budget/demo/probe_results.txt"
JPEG_REF = "results/viewers/jpeg_reference/"
F2B = F2B_DIR + "tables.md"
H2B = H2B_DIR + "tables.md"
LEGO_OWNER = ("owner_seed0", "owner_seed1", "owner_seed2")
LEGO_BLIND = ("blind_seed0", "blind_seed1", "blind_seed2")
LEGO_RAW = "results/nerf_synthetic_lego/raw.log"
BONSAI = "results/mipnerf360_bonsai/tables.md"
BONSAI_RAW = "results/mipnerf360_bonsai/raw.log"
BONSAI_MODEL = "results/mipnerf360_bonsai/model_info.txt"
BONSAI_FULL = "results/mipnerf360_bonsai/full_800x533/tables.md"
BONSAI_FULL_RUN = "results/mipnerf360_bonsai/full_800x533/runs/both_seed0_auto/embed.log"
BONSAI_FULL_PEAK = "results/mipnerf360_bonsai/full_800x533/peak_memory.txt"
BONSAI_1M = "results/mipnerf360_bonsai/full_density_1m/tables.md"
BONSAI_1M_RUN = "results/mipnerf360_bonsai/full_density_1m/runs/both_seed0_auto/embed.log"
BONSAI_1M_PEAK = "results/mipnerf360_bonsai/full_density_1m/peak_memory.txt"
LEGO_DEFAULT = "results/nerf_synthetic_lego/tables_default.md"  # today's default, session 33
EMBED_1M = "results/embed_1m/synthetic_1m_crop_curve.log"
EMBED_1M_AUTO = "results/embed_1m/synthetic_1m_auto_memory.log"
FAST_LOADED = "results/testing/fast_tier_3feac90.txt"
# The paper's own figures, cited beside ours: read from its LaTeX source, which CI keeps beside the
# clone (../shared/paper/); such a figure is named by the word "paper" beside it, not by its path.
PAPER = "../shared/paper/water-gs.tex"
NAMED_AS = {PAPER: r"\bpaper\b"}
# Table 1, LLFF, "Ours": identity / GN / dropout / crop BER (%).
PAPER_TABLE1_LLFF = grep(PAPER, r"\{LLFF\}.*?~ & Ours & \\textbf\{([\d.]+)\} & \\textbf\{([\d.]+)\} & "
                         r"\\textbf\{([\d.]+)\} & \\textbf\{([\d.]+)\}", re.S)
# Table 1, Mip-NeRF 360, "Ours" (only identity in bold).
PAPER_TABLE1_MIP = grep(PAPER, r"\{MIP-NeRF360\}.*?~ & Ours & \\textbf\{([\d.]+)\} & ([\d.]+) & ([\d.]+) & ([\d.]+)",
                        re.S)
# Held-out PSNR on LLFF: 3DGS (Table 2) minus WATER-GS at 48 bits (Table 5): the cost of the watermark.
PAPER_COST_LLFF = difference(grep(PAPER, r"^\s*3DGS & N/A & ([\d.]+)"), grep(PAPER, r"^\s*48 bits & [\d.]+ & ([\d.]+)"))

RAW_PSNR = "PSNR vs photos"
FROM_RAW = "PSNR vs raw renders"


def seeds(path, column, runs=("owner_seed0", "owner_seed1", "owner_seed2"), reading="owner", index=0):
    return [cell(path, (run, reading), column, index) for run in runs]


def probe(label, field, path):
    """A number of one line of single_view_probe.sh's results.txt (path): the label's line, the figure
    after field (e.g. 'owner held ', 'free48 ', 'vs raw ')."""
    return grep(path, r"^" + re.escape(label) + r"\s.*?" + re.escape(field) + r"\s*" + NUMBER)



def blind_and_costs(demo_label, fern_label, demo_run):
    """Session 38's viewer rows end alike: one held-out view read blind (demo, fern), PSNR from the
    raw renders (demo, fern), then raw -> watermarked against the photos (demo, fern)."""
    demo, fern = JLS + "demo_probe_results.txt", JLS + "fern_probe_results.txt"
    return [probe(demo_label, "held", demo), probe(fern_label, "held", fern),
            probe(demo_label, "vs raw", demo), probe(fern_label, "vs raw", fern),
            grep(JLS + demo_run + "/eval.md", r"raw vs ground truth \| ([\d.]+)"), probe(demo_label, "PSNR", demo),
            grep(JLS + "fern_raw.log", r"held-out views \(3\): PSNR ([\d.]+)"), probe(fern_label, "PSNR", fern)]


AUTO = ("owner_seed0_autor", "owner_seed1_autor", "owner_seed2_autor")

def diffs(path, runs, reading="owner"):
    """watermarked - raw PSNR against the photos, one figure per run (negative: a loss)."""
    return [difference(cell(path, (r, reading), RAW_PSNR, 1), cell(path, (r, reading), RAW_PSNR, 0))
            for r in runs]


def losses(path, runs, reading="owner"):
    """raw - watermarked PSNR against the photos, one figure per run (positive: a loss)."""
    return [scaled(-1, d) for d in diffs(path, runs, reading)]


SEEDS = ("owner_seed0", "owner_seed1", "owner_seed2")
AUTO = ("owner_seed0_autor", "owner_seed1_autor", "owner_seed2_autor")
ATTACKS = ("identity", "gn:0.01", "dropout:0.1", "crop:0.1")


def table1(path, runs, attacks=ATTACKS, index=0, reading="owner"):
    """Table 1 cells (index 0: the per-image BER of one draw; 4: the mean over draws, 5: the
    largest draw, 6: the most aggregated bits wrong, 8: draws read 'present')."""
    return [cell(path, (r, reading), a, index) for r in runs for a in attacks]


def single_views(path, runs, column, index=0, reading="owner"):
    return [cell(path, (r, reading), column, index) for r in runs]


def crop_draws(run, field):
    """Each crop:0.1 draw's figure (view_ber, bit_errors) as the owner, from a horns draws run's eval JSON."""
    return json_at(f"results/real_llff/horns_252x189_draws/table1_{run}.json", "robustness",
                   "?attack=crop:0.1&model=watermarked", "draws", "owner", "per_draw", "*", field)


def report_row(attack, verdict):
    """Bits wrong of the demo report's row for the watermarked file under attack (a name or its
    start), which must read verdict ("present", "absent", "inconclusive")."""
    return grep("results/demo/report.html", r'<tr><td>watermarked</td><td class="attack">' + re.escape(attack)
                + r'[^<]*</td>.*?\((\d+) / 48\)</td>.*?class="' + verdict + '"')


CLAIMS = [
    # -- the introduction --
    Claim("reads about {}% of the bits on its own",
          combine(lambda v: 100 - 100 * v[0], json_at(DEMO_HELD, "owner", "view_ber", "mean"))),
    Claim("stay {} dB PSNR from the raw model's ({} dB of held-out PSNR",
          grep(DEMO, r"watermarked vs the raw renders: ([\d.]+) dB"),
          combine(lambda v: v[0] - v[1], grep(DEMO, r"held-out PSNR vs the photos: raw ([\d.]+) dB, watermarked ([\d.]+) dB"))),
    Claim("one held-out photo's viewpoint alone {}-{}% of the bits wrong per image",
          span(*[cell(d, (r, "blind"), "held-out mean") for d in (F2B, H2B) for r in T38])),
    Claim("(fern and horns at 252x189, seeds 0-2, {}-{}\ndB from the raw renders",
          span(*[cell(d, (r, "owner"), FROM_RAW) for d in (F2B, H2B) for r in T38])),
    Claim("fixed blind weight: {}-{}% at {}-{} dB, seed 0)",
          span(cell(F2B, ("both_seed0", "blind"), "identity"), cell(H2B, ("both_seed0", "blind"), "identity")),
          span(cell(F2B, ("both_seed0", "owner"), FROM_RAW), cell(H2B, ("both_seed0", "owner"), FROM_RAW))),
    Claim("32 draws: {}% of bits per image against {}% with the distortion layers always on;",
          mean(*seeds(DRAWS, "crop:0.1", runs=AUTO, index=4)), mean(*seeds(DRAWS, "crop:0.1", index=4))),

    # -- the paper's figures set beside ours (its LaTeX source) --
    Claim("LLFF figure, read blind: {}%)", combine(lambda v: v[0], PAPER_TABLE1_LLFF)),
    Claim("(the paper, LLFF: {} dB)", PAPER_COST_LLFF),

    # -- the demo's run (scripts/run_demo.sh), its summary and what the text reads from it --
    Claim("2 cores with nothing else running) it took\n{} s: training {} s, embedding {}m{}s",
          grep(DEMO, r"^== demo summary .*, (\d+) s\)$"),
          grep(DEMO, r"^train: \d+ iterations in ([\d.]+)s"), grep(DEMO, r"^embed: \d+ iterations in (\d+)m(\d+)s")),
    Lines("== demo summary (message", DEMO,
          normalize=lambda line: re.sub(r"decoder \S*/watermark/models/", "decoder .../watermark/models/", line)),
    Claim("The raw model reads {} of 48 bits right",
          combine(lambda v: 48 - round(v[0] * 48 / 100), grep(DEMO, r"^raw\s+BER ([\d.]+)%"))),
    Claim("one camera's render alone misses {}% of the bits ({}% after Gaussian noise)",
          grep(DEMO, r"^wm\s+BER.*?one view: BER mean ([\d.]+)%"),
          grep(DEMO, r"^wm_gn\s+BER.*?one view: BER mean ([\d.]+)%")),
    Claim("read {}, {}, {}, {}, {} and {} bits wrong one by one ({}%),",
          json_at(DEMO_HELD, "owner", "views", "*", "bit_errors"),
          scaled(100, json_at(DEMO_HELD, "owner", "view_ber", "mean"))),
    Claim("48 free viewpoints between cameras {}% ({} of them \"present\" alone under a key; the worst {} and {} of 48;",
          scaled(100, json_at(DEMO_FREE, "owner", "view_ber", "mean")),
          combine(lambda v: sum(x <= 7 for x in v), json_at(DEMO_FREE, "owner", "views", "*", "bit_errors")),
          combine(lambda v: sorted(v)[-2:], json_at(DEMO_FREE, "owner", "views", "*", "bit_errors"))),
    Claim("one held-out view alone misses {}% (the paper's", scaled(100, json_at(DEMO_HELD, "view_ber", "mean"))),
    Claim("so renders saved as JPEG 75 read {}% of the bits wrong a view as the owner",
          grep("results/demo/report.html", r'class="attack">jpeg:75 .*?<td class="num">([\d.]+)% / ')),
    Claim("The 6 held-out views alone read {} / {}% a view at JPEG 90 / 75, each set \"present\" together",
          *[combine(lambda v: 100 * v[0], json_at(JPEG_REF + f"default_t38_jpeg{q}.json", "owner", "view_ber", "mean"))
            for q in (90, 75)]),
    Claim("(the owner's reading alone at {} dB, \"inconclusive\" blind",
          grep("results/demo/first_default_run_demo.log", r"watermarked vs the raw renders: ([\d.]+) dB")),
    Claim("the first default {}%, a figure taken with",
          grep("results/demo/first_default_report.html", r'class="attack">jpeg:75 .*?<td class="num">([\d.]+)% / ')),
    Claim("**{} dB PSNR from the raw model's** on the held-out views, and the watermark costs {} dB",
          grep(DEMO, r"watermarked vs the raw renders: ([\d.]+) dB"),
          combine(lambda v: v[0] - v[1], grep(DEMO, r"held-out PSNR vs the photos: raw ([\d.]+) dB, watermarked ([\d.]+) dB"))),
    # -- the figures table, row by row --
    Claim("gn / dropout / crop {} / {}-{} / **{}-{}%** ({} draws of 32 above 1%, largest {}%); aggregated at most "
          "{} of 48, 'present' on {} of 32 draws of each, every seed; single views alone {} of 8 held-out, {} of 48 "
          "free; auto crop {}-{}%",
          highest(*table1(DRAWS, SEEDS, ["gn:0.01"], 4)), span(*table1(DRAWS, SEEDS, ["dropout:0.1"], 4)),
          span(*table1(DRAWS, SEEDS, ["crop:0.1"], 4)),
          highest(*[combine(lambda v: sum(x > 0.01 for x in v), crop_draws(r, "view_ber")) for r in SEEDS]),
          highest(*table1(DRAWS, SEEDS, ["crop:0.1"], 5)),
          highest(*table1(DRAWS, SEEDS, ATTACKS[1:], 6)), lowest(*table1(DRAWS, SEEDS, ATTACKS[1:], 8)),
          lowest(*single_views(DRAWS, SEEDS + AUTO, "held-out views")),
          lowest(*single_views(DRAWS, SEEDS + AUTO, "free 'present'")),
          span(*table1(DRAWS, AUTO, ["crop:0.1"], 4))),
    Claim("one crop draw of 32 'inconclusive' ({} of 48)", highest(crop_draws("owner_seed2_autor", "bit_errors"))),
    Claim("why the default keeps the layers | {}-{}; auto {}-**{}** | {} -> {}-{}; auto {}-{} |",
          span(*seeds(DRAWS, FROM_RAW)), span(*seeds(DRAWS, FROM_RAW, runs=AUTO)),
          cell(DRAWS, ("owner_seed0", "owner"), RAW_PSNR), span(*seeds(DRAWS, RAW_PSNR, index=1)),
          span(*seeds(DRAWS, RAW_PSNR, runs=AUTO, index=1))),
    Claim("| {} of 20 \"present\" alone (whole, cropped 80%, shrunk 75%; {} of 20 registered; mean {}% wrong an image), {} of 20 read blind; the raw "
          "model's {} of 20 | {} dB |",
          grep(DETECT + "results.txt", r"wm: (\d+) of 20 present"),
          count_where(DETECT + "shots_wm/detect.json", ("owner", "registrations", "*", "registered"), 1),
          scaled(100 / 48, mean(json_at(DETECT + "shots_wm/detect.json", "owner", "views", "*", "bit_errors"))),
          grep(DETECT + "results.txt", r"\), (\d+) blind \|"),
          grep(DETECT + "results.txt", r"raw control: (\d+) present"),
          grep("results/blind_budget/demo_iterations/results.txt", r"^default_seed0_it1500 .*vs raw ([\d.]+)")),
    Claim("OpenSplat 1.1.5 on the demo ({} Gaussians, SH {}, its default normalised frame; built and trained by "
          "`build_opensplat.sh`)",
          grep("results/third_party/opensplat_demo/README.md", r"([\d,]+) Gaussians, SH degree (\d)")),
    Claim("aligned without options (scale {} where OpenSplat's is {}; taken as it is: {} dB vs photos); held-out "
          "{} / {} / {}% ({} of 6 \"present\" alone each); read blind one held-out view {}-{}%, the 6 together "
          "\"present\"; another scene's workspace (bonsai) refused in one line, {} s "
          "| **{} / {} / {} dB** | {} -> {}-{} ({} to {}) |",
          grep("results/third_party/opensplat_demo/extract_owner_s0.log", r"scale ([\d.]+)"),
          grep("results/third_party/opensplat_demo/README.md", r"scaled by 1 / ([\d.]+)"),
          grep(OPENSPLAT, r"^seed 0: held-out PSNR, --align off: watermarked vs ground truth ([\d.]+)"),
          *[grep(OPENSPLAT, rf"^seed {i}: owner's reading, each held-out view alone: mean BER ([\d.]+)%")
            for i in range(3)],
          lowest(*[grep(OPENSPLAT, rf"^seed {i}: owner's reading.*?(\d+) of 6 'present'") for i in range(3)]),
          span(*[combine(lambda v: 100 * sum(v) / (48 * len(v)),
                         json_at(f"results/third_party/opensplat_demo/extract_owner_s{i}.json", "views", "*",
                                 "bit_errors"))
                 for i in range(3)]),
          grep("results/third_party/opensplat_demo/README.md", r"refused in one line, ([\d.]+) s"),
          *[grep(OPENSPLAT, rf"^seed {i}: held-out PSNR, placed: .*?raw renders ([\d.]+) dB") for i in range(3)],
          grep(OPENSPLAT, r"^seed 0: held-out PSNR, placed: .*?raw vs ground truth ([\d.]+) dB"),
          span(*[grep(OPENSPLAT, rf"^seed {i}: held-out PSNR, placed: watermarked vs ground truth ([\d.]+)")
                 for i in range(3)]),
          span(*[difference(grep(OPENSPLAT, rf"^seed {i}: held-out PSNR, placed: watermarked vs ground truth ([\d.]+)"),
                            grep(OPENSPLAT, rf"^seed {i}: held-out PSNR, placed: .*?raw vs ground truth ([\d.]+)"))
                 for i in range(3)])),
    # -- testing: the everyday tier, as scripts/time_fast_tier.sh measured it --
    Claim("`ctest --test-dir build` runs {} tests ({} labelled `slow`;",
          grep(FAST, r"^tests: \d+ in the tier, \d+ labelled slow, (\d+) in all"),
          grep(FAST, r"^tests: \d+ in the tier, (\d+) labelled slow")),
    Claim("2 cores: {} tests) and runs the other {} without COLMAP in {} s at `-j2` ({} skip without a GPU, saying why)",
          grep(FAST, r"^tests: \d+ in the tier, (\d+) labelled slow"), grep(FAST, r"^tests: (\d+) in the tier"),
          grep(FAST, r"^wall: (\d+) s"), count(FAST, r"\(Skipped\)$")),
    Claim("(load average {} before, {} after; the tests' CPU time, {} s,",
          grep(FAST, r"^load average \(1, 5, 15 min\) before: ([\d.]+)"),
          grep(FAST, r"^load average \(1, 5, 15 min\) before: .*; after: ([\d.]+)"),
          grep(FAST, r"^cpu \(user \+ sys, all tests\): (\d+) s")),
    Claim("logs its calls first on PATH: {} calls", grep(FAST, r"^colmap calls: (\d+)")),
    Claim("the same tier took {} s\nunder a load of {}-{} on another day",
          grep(FAST_LOADED, r"^wall: (\d+) s"),
          grep(FAST_LOADED, r"^load average \(1, 5, 15 min\) before: ([\d.]+)"),
          grep(FAST_LOADED, r"^load average \(1, 5, 15 min\) before: .*; after: ([\d.]+)")),
    Claim("saying why), {} failed", grep(FAST, r"^\d+% tests passed, (\d+) tests failed"), name="the fast tier's failures"),
    # -- the second table --
    Claim("| attacks on the file, as the owner (48 cameras) | {} of 48 wrong, \"present\": `gn:0.01`, `dropout:0.1`, "
          "`crop:0.1`, `sh0`, `fp16`, `shuffle`, `similarity`, `prune:0.05`, `resize:0.5`, `jpeg:75`, `jpeg:50`; "
          "`quant:8` \"absent\" ({} of 48)",
          highest(*[report_row(a, "present") for a in ("gn:0.01", "dropout:0.1", "crop:0.1", "sh0", "fp16", "shuffle",
                                                       "similarity:", "prune:0.05", "resize:0.5", "jpeg:75",
                                                       "jpeg:50")]),
          report_row("quant:8", "absent")),
    Claim("read blind, one camera's render alone: {}% untouched, {}% after `gn:0.01`, {}% after `jpeg:75` |",
          *[grep("results/demo/report.html", r'<tr><td>watermarked</td><td class="attack">' + re.escape(a)
                 + r'[^<]*</td>.*?<span class="small">blind ([\d.]+)% / ') for a in ("identity", "gn:0.01", "jpeg:75")]),
    Claim("| the demo above, {} s on 2 cores with nothing else running (training {} s, embedding {}m{}s)",
          grep(DEMO, r"^== demo summary .*, (\d+) s\)$"),
          grep(DEMO, r"^train: \d+ iterations in ([\d.]+)s"), grep(DEMO, r"^embed: \d+ iterations in (\d+)m(\d+)s")),
    Claim("| {} single reads of 4 unmarked models: single keys {}-{}x the binomial rate at 1e-2",
          cell(NULL, ("text:WGS-26, key 0", "1", "0.01"), "Trials"),
          span(*[cell(NULL, (f"text:WGS-26, key {k}", "1", "0.01"), "Empirical / binomial") for k in range(3)])),
    Claim("| train {} it/s, embed {} it/s (blind default)",
          grep(GPU, r"^train: .*\(([\d.]+) it/s\)"),
          combine(lambda v: v[0] / v[1], grep(GPU, r"^embed: (\d+) iterations in ([\d.]+)s"))),
    # -- what works --
    Claim("one file for both readers by default: the owner's reading at {} dB from the raw renders with every camera "
          "and the blind reading \"present\" over the cameras together, one view blind {}% on the demo",
          grep(DEMO, r"watermarked vs the raw renders: ([\d.]+) dB"), scaled(100, json_at(DEMO_HELD, "view_ber", "mean"))),
    Claim("JPEG-90 renders of free viewpoints read \"present\" alone {} of 20 times with the default",
          grep(DETECT + "results.txt", r"wm: (\d+) of 20 present")),
    Claim("all {} parity tests pass, compute-sanitizer clean, the demo trains at {} it/s and embeds at {} it/s",
          grep("results/gpu/h200-2026-11-26/README.md", r"\((\d+) pass"),
          grep(GPU, r"^train: .*\(([\d.]+) it/s\)"),
          combine(lambda v: v[0] / v[1], grep(GPU, r"^embed: (\d+) iterations in ([\d.]+)s"))),
    Claim("built from photos only) | {}% ({}) / {}% | {} dB | {} (raw {}: {}) |",
          probe("residual2_inria", "held", BLIND),
          grep(BLIND, r"^residual2_inria\s+held\s+[\d.]+% p90\s+([\d.]+)"),
          grep(BLIND, r"^residual2_inria\s.*?\| free\s+([\d.]+)%"), probe("residual2_inria", "vs raw", BLIND),
          probe("residual2_inria", "PSNR", BLIND), BLIND_RAW_PSNR,
          difference(probe("residual2_inria", "PSNR", BLIND), BLIND_RAW_PSNR)),
    Claim("| {} s an iteration (render {}, decoder {}, backward {}, Adam {} s): {} min for 1,500 iterations; "
          "whole frames (`--crop_size 0`) {} s, {} min, the decoder {} s of it; peak memory {} GB, whole frames {} GB",
          combine(lambda v: [v[0] / 1e3, v[2] / 1e3, v[4] / 1e3, v[5] / 1e3, v[7] / 1e3, v[0] * 1.5 / 60],
                  grep(EMBED_1M, r"^4 layers, crop auto, embed's defaults" + r"\s+([\d.]+)" * 8)),
          combine(lambda v: [v[0] / 1e3, v[0] * 1.5 / 60, v[4] / 1e3],
                  grep(EMBED_1M, r"^4 layers, full frame, embed's defaults" + r"\s+([\d.]+)" * 5)),
          scaled(1e-6, grep(EMBED_1M_AUTO, r"Maximum resident set size \(kbytes\): (\d+)")),
          scaled(1e-6, grep(EMBED_1M, r"Maximum resident set size \(kbytes\): (\d+)"))),
    Claim("| **NeRF-synthetic lego** (`transforms_importer`: {} training and {} test views at 200x200 on white, {} random "
          "initial points; raw {} Gaussians), seeds 0-2 | as the owner {} / {} / {}% per test view / 48 free viewpoints "
          "{}-{}%; `--reading blind`, the anchors' reading: Table 1 blind per image identity {} / {} / {}%, gn {}-{}%, "
          "dropout {}-{}%, crop {}-{}%; free viewpoints {}-{}%",
          grep(LEGO_RAW, r"^train: (\d+) training views, (\d+) held out, \d+x\d+, (\d+) SfM points"),
          grep(LEGO, r"^Raw model: (\d+) Gaussians"),
          *single_views(LEGO, LEGO_OWNER, "held-out mean", 0),
          span(*single_views(LEGO, LEGO_OWNER, "free mean", 0)),
          *table1(LEGO, LEGO_BLIND, ("identity",), reading="blind"),
          *[span(*table1(LEGO, LEGO_BLIND, (a,), reading="blind")) for a in ("gn:0.01", "dropout:0.1", "crop:0.1")],
          span(*single_views(LEGO, LEGO_BLIND, "free mean", 0, "blind"))),
    Claim("| owner {} / {} / {}; blind {} / {} / {} dB | {} -> {}-{} / {}-{} |",
          *[cell(LEGO, (r, "owner"), FROM_RAW) for r in LEGO_OWNER],
          *[cell(LEGO, (r, "blind"), FROM_RAW) for r in LEGO_BLIND],
          cell(LEGO, ("owner_seed0", "owner"), RAW_PSNR, 0),
          span(*[cell(LEGO, (r, "owner"), RAW_PSNR, 1) for r in LEGO_OWNER]),
          span(*[cell(LEGO, (r, "blind"), RAW_PSNR, 1) for r in LEGO_BLIND])),
    Claim("| **NeRF-synthetic lego with the default** (`embed` with only the message; the same raw model), seeds 0-2 | "
          "as the owner {} / {} / {}% per test view ({} / {} / {} of 200 \"present\" alone), 48 free viewpoints {}-{}%; "
          "read blind, the anchors' reading: one test view {} / {} / {}%, Table 1 gn {}-{}%, dropout {}-{}%, crop {}-{}%; "
          "all 300 cameras together, blind: {} / {} / {} of 48 wrong",
          *single_views(LEGO_DEFAULT, BOTH_SEEDS, "held-out mean", 0),
          *single_views(LEGO_DEFAULT, BOTH_SEEDS, "held-out views 'present'", 0),
          span(*single_views(LEGO_DEFAULT, BOTH_SEEDS, "free mean", 0)),
          *single_views(LEGO_DEFAULT, BOTH_SEEDS, "held-out mean", 0, "blind"),
          *[span(*table1(LEGO_DEFAULT, BOTH_SEEDS, (a,), reading="blind")) for a in ("gn:0.01", "dropout:0.1", "crop:0.1")],
          *[cell(LEGO_DEFAULT, (r,), "bits wrong") for r in BOTH_SEEDS]),
    Claim("worse than either pure reading above: most of each frame is white background, where no splat can carry the "
          "message | **{} / {} / {} dB** | {} -> {}-{} |",
          *[cell(LEGO_DEFAULT, (r, "owner"), FROM_RAW) for r in BOTH_SEEDS],
          cell(LEGO_DEFAULT, ("both_seed0", "owner"), RAW_PSNR, 0),
          span(*[cell(LEGO_DEFAULT, (r, "owner"), RAW_PSNR, 1) for r in BOTH_SEEDS])),
    Claim("| **Mip-NeRF 360 bonsai** (real: {} photos of a public 800x533 copy, reconstructed here: {} of {}; raw {} "
          "Gaussians at {}x{}, {} dB held-out), the default, seeds 0-2 | as the owner {} / {} / {}% per held-out view "
          "({} views), 48 free viewpoints {}-{}%; read blind: one held-out view {} / {} / {}%, free viewpoints {}-{}%; "
          "Table 1 per image read blind, identity / gn / dropout / crop, seed 0: {} / {} / {} / {}%, every cell of the "
          "three seeds at most {}% (the paper, Mip-NeRF 360, blind: {} / {} / {} / {}%); all {} cameras together, "
          "blind: {} of 48 wrong on every seed; `--reading blind`, seed 0: {}% a held-out view at {} dB",
          grep(BONSAI_MODEL, r"^Images: (\d+)"), grep(BONSAI_MODEL, r"^Registered images: (\d+)"),
          grep(BONSAI_MODEL, r"^Images: (\d+)"), grep(BONSAI, r"^Raw model: (\d+) Gaussians"),
          grep(BONSAI_RAW, r"^train: \d+ training views, \d+ held out, (\d+)x(\d+)"),
          grep(BONSAI, r"held-out PSNR ([\d.]+) dB"),
          *single_views(BONSAI, BOTH_SEEDS, "held-out mean", 0),
          grep(BONSAI_RAW, r"^train: \d+ training views, (\d+) held out"),
          span(*single_views(BONSAI, BOTH_SEEDS, "free mean", 0)),
          *single_views(BONSAI, BOTH_SEEDS, "held-out mean", 0, "blind"),
          span(*single_views(BONSAI, BOTH_SEEDS, "free mean", 0, "blind")),
          *table1(BONSAI, ("both_seed0",), reading="blind"),
          highest(*table1(BONSAI, BOTH_SEEDS, reading="blind")), PAPER_TABLE1_MIP,
          cell(BONSAI, ("both_seed0",), "cameras"),
          highest(*[cell(BONSAI, (r,), "bits wrong") for r in BOTH_SEEDS]),
          cell(BONSAI, ("blind_seed0", "blind"), "held-out mean"), cell(BONSAI, ("blind_seed0", "blind"), FROM_RAW)),
    Claim("| **{} / {} / {} dB** | {} -> {} / {} / {} | `download_bonsai_800.sh`",
          *[cell(BONSAI, (r, "owner"), FROM_RAW) for r in BOTH_SEEDS],
          cell(BONSAI, ("both_seed0", "owner"), RAW_PSNR, 0),
          *[cell(BONSAI, (r, "owner"), RAW_PSNR, 1) for r in BOTH_SEEDS]),
    Claim("| **the default at bonsai's full 800x533** (`--crop_size auto`: a {} px decoder crop at {}x{}; the same scene "
          "reconstructed again, its raw model trained at 199x132 and seen at full size: {} Gaussians, {} dB held-out "
          "against the photos), seed 0 | as the owner {}% per held-out view ({} views), 48 free viewpoints {}%; read "
          "blind: one held-out view {}% (p90 {}), free viewpoints {}%; Table 1 per image read blind, identity / gn / "
          "dropout / crop: {} / {} / {} / {}% (the paper, Mip-NeRF 360, blind: {} / {} / {} / {}%); all {} cameras "
          "together, blind: {} of 48 wrong; embedding {}m{}s on 2 cores (AMD EPYC), peak memory {} GB | **{} dB** | "
          "{} -> {} |",
          grep(BONSAI_FULL_RUN, r", crop (\d+) \(auto"), grep(BONSAI_FULL_RUN, r"views (\d+)x(\d+), 48-bit"),
          grep(BONSAI_FULL, r"^Raw model: (\d+) Gaussians"), cell(BONSAI_FULL, ("both_seed0_auto", "owner"), RAW_PSNR, 0),
          *single_views(BONSAI_FULL, ("both_seed0_auto",), "held-out mean", 0),
          grep(BONSAI_FULL, r"\| both_seed0_auto \| owner \| [^|]+\| \d+ of (\d+) \|"),
          *single_views(BONSAI_FULL, ("both_seed0_auto",), "free mean", 0),
          *single_views(BONSAI_FULL, ("both_seed0_auto",), "held-out mean", 0, "blind"),
          *single_views(BONSAI_FULL, ("both_seed0_auto",), "held-out mean", 1, "blind"),
          *single_views(BONSAI_FULL, ("both_seed0_auto",), "free mean", 0, "blind"),
          *table1(BONSAI_FULL, ("both_seed0_auto",), reading="blind"), PAPER_TABLE1_MIP,
          cell(BONSAI_FULL, ("both_seed0_auto",), "cameras"), cell(BONSAI_FULL, ("both_seed0_auto",), "bits wrong"),
          grep(BONSAI_FULL_RUN, r"^embed: 1500 iterations in (\d+)m(\d+)s"),
          scaled(1e-6, grep(BONSAI_FULL_PEAK, r"peak_rss_kb (\d+)")),
          cell(BONSAI_FULL, ("both_seed0_auto", "owner"), FROM_RAW),
          *[cell(BONSAI_FULL, ("both_seed0_auto", "owner"), RAW_PSNR, k) for k in (0, 1)]),
    Claim("| **the default on bonsai refined to full density at 800x533**: the raw model above refined at {}x{} by "
          "`train --init_path` in two passes ({} Gaussians, SH degree 3, {} dB held-out against the photos), "
          "`--crop_size auto` ({} px), seed 0 | as the owner {}% per held-out view ({} views), 48 free viewpoints {}%; "
          "read blind: one held-out view {}% (p90 {}), free viewpoints {}%; Table 1 per image read blind, identity / gn / "
          "dropout / crop: {} / {} / {} / {}% (the paper, Mip-NeRF 360, blind: {} / {} / {} / {}%); all {} cameras "
          "together, blind: {} of 48 wrong; embedding {}m{}s on 2 cores (AMD EPYC; {} ms an iteration: render {}, "
          "decoder {}, backward {}, Adam {} ms), peak memory {} GB (goal: 60 min, 8 GiB) | **{} dB** | {} -> {} |",
          grep(BONSAI_1M_RUN, r"views (\d+)x(\d+), 48-bit"),
          grep(BONSAI_1M, r"^Raw model: (\d+) Gaussians"), cell(BONSAI_1M, ("both_seed0_auto", "owner"), RAW_PSNR, 0),
          grep(BONSAI_1M_RUN, r", crop (\d+) \(auto"),
          *single_views(BONSAI_1M, ("both_seed0_auto",), "held-out mean", 0),
          grep(BONSAI_1M, r"\| both_seed0_auto \| owner \| [^|]+\| \d+ of (\d+) \|"),
          *single_views(BONSAI_1M, ("both_seed0_auto",), "free mean", 0),
          *single_views(BONSAI_1M, ("both_seed0_auto",), "held-out mean", 0, "blind"),
          *single_views(BONSAI_1M, ("both_seed0_auto",), "held-out mean", 1, "blind"),
          *single_views(BONSAI_1M, ("both_seed0_auto",), "free mean", 0, "blind"),
          *table1(BONSAI_1M, ("both_seed0_auto",), reading="blind"), PAPER_TABLE1_MIP,
          cell(BONSAI_1M, ("both_seed0_auto",), "cameras"), cell(BONSAI_1M, ("both_seed0_auto",), "bits wrong"),
          grep(BONSAI_1M_RUN, r"^embed: 1500 iterations in (\d+)m(\d+)s"),
          grep(BONSAI_1M_RUN, r"^embed: per iteration ([\d.]+) ms = distortion [\d.]+ \+ render ([\d.]+) \+ "
               r"image loss [\d.]+ \+ decoder ([\d.]+) \+ backward ([\d.]+) \+ density [\d.]+ \+ adam ([\d.]+)"),
          scaled(1e-6, grep(BONSAI_1M_PEAK, r"embed .*peak_rss_kb (\d+)")),
          cell(BONSAI_1M, ("both_seed0_auto", "owner"), FROM_RAW),
          *[cell(BONSAI_1M, ("both_seed0_auto", "owner"), RAW_PSNR, k) for k in (0, 1)]),
    Claim("fly-through of the demo's watermarked file ({} frames between two held-out cameras, H.264 CRF 23 at {} kbit/s), "
          "read as the owner by `detect` | \"present\" from frame {}; {} of {} frames \"present\" alone (mean {}% a frame), "
          "all together {} of 48 wrong; the raw model's recording \"absent\" ({} of 48)",
          grep(RECORDING, r"^gs3d_wm\t\d+\t\d+ of (\d+)"), grep(RECORDING, r"^gs3d_wm\t(\d+)"),
          grep(RECORDING, r"^gs3d_wm\t(?:[^\t]*\t){6}(\d+)"), grep(RECORDING, r"^gs3d_wm\t(?:[^\t]*\t){4}(\d+) /"),
          grep(RECORDING, r"^gs3d_wm\t\d+\t\d+ of (\d+)"), grep(RECORDING, r"^gs3d_wm\t(?:[^\t]*\t){3}([\d.]+)%"),
          grep(RECORDING, r"^gs3d_wm\t(?:[^\t]*\t){5}\w+ \((\d+) of 48\)"),
          grep(RECORDING, r"^gs3d_raw\t(?:[^\t]*\t){5}\w+ \((\d+) of 48\)")),
    Claim("| {} s an image: registration {} s, refinement {} s, decoding {} s for all {} (the refinement's Jacobian "
          "from the image gradient; with finite differences over renders the same two screenshots took {} s an image "
          "against {}) |",
          *[json_at(DETECT_COST + "old24_gradient.json", "time", k)
            for k in ("per_image_s", "registration_s", "refinement_s", "decoding_s", "images")],
          json_at(DETECT_COST + "two_renders.json", "time", "per_image_s"),
          json_at(DETECT_COST + "two_gradient.json", "time", "per_image_s")),
    Claim("| gaussian-splats-3d {} of 6 \"present\" alone, mean {}% (watergs' reference: {}%); PlayCanvas {} of 6, {}% ({}%); "
          "the raw model's screenshots \"absent\" {} of 6 and {} of 6 | {} dB |",
          shots(VIEWER_BER, "gs3d_wm", "present"), shots(VIEWER_BER, "gs3d_wm", "mean"), shots(VIEWER_BER, "gs3d_wm", "mean", setting="watergs"),
          shots(VIEWER_BER, "playcanvas_wm", "present"), shots(VIEWER_BER, "playcanvas_wm", "mean"), shots(VIEWER_BER, "playcanvas_wm", "mean", setting="watergs"),
          shots(VIEWER_BER, "gs3d_raw", "absent"), shots(VIEWER_BER, "playcanvas_raw", "absent"),
          grep("results/viewers/reference_conventions/README.md", r"\(`wm_embed.log`; ([\d.]+) dB from")),
    Claim("(downloaded and reconstructed again: fern {} photos, raw {} dB; horns {}, raw {} dB), seed 0 | as the owner "
          "{}% / {}% on both; read blind: fern {}% (p90 {}) / {}%, horns {}% (p90 {}) / {}%; Table 1 per image read "
          "blind, identity / gn / dropout / crop: fern {} / {} / {} / {}%, horns {} / {} / {} / {}% (the paper, LLFF, "
          "blind: {} / {} / {} / {}%); as the owner {}% each; every camera together, blind: {} of 48 wrong on both",
          grep(F2B_DIR + "reconstruct.log", r"(\d+) of \d+ photos registered"), cell(F2B, ("both_seed0", "owner"), RAW_PSNR, 0),
          grep(H2B_DIR + "reconstruct.log", r"(\d+) of \d+ photos registered"), cell(H2B, ("both_seed0", "owner"), RAW_PSNR, 0),
          highest(cell(F2B, ("both_seed0", "owner"), "held-out mean"), cell(H2B, ("both_seed0", "owner"), "held-out mean")),
          highest(cell(F2B, ("both_seed0", "owner"), "free mean"), cell(H2B, ("both_seed0", "owner"), "free mean")),
          cell(F2B, ("both_seed0", "blind"), "held-out mean"), cell(F2B, ("both_seed0", "blind"), "held-out mean", 1),
          cell(F2B, ("both_seed0", "blind"), "free mean"),
          cell(H2B, ("both_seed0", "blind"), "held-out mean"), cell(H2B, ("both_seed0", "blind"), "held-out mean", 1),
          cell(H2B, ("both_seed0", "blind"), "free mean"),
          *table1(F2B, ("both_seed0",), reading="blind"), *table1(H2B, ("both_seed0",), reading="blind"),
          *[combine(lambda v, k=k: v[k], PAPER_TABLE1_LLFF) for k in range(4)],
          highest(*table1(F2B, ("both_seed0",)), *table1(H2B, ("both_seed0",))),
          highest(grep(F2B_DIR + "runs/both_seed0/all_blind.txt", r"aggregated over .*\((\d+) of 48 bits\)"),
                  grep(H2B_DIR + "runs/both_seed0/all_blind.txt", r"aggregated over .*\((\d+) of 48 bits\)")),
          ),
    Claim("--target_psnr`; on the two real LLFF scenes measured, one held-out view read blind at under {}%:",
          combine(lambda v: math.ceil(max(v)),
                  *[cell(d, (r, "blind"), "held-out mean") for d in (F2B, H2B) for r in T38])),
    Claim("one view read blind under {}% on fern and horns (below the paper's {}%;",
          combine(lambda v: math.ceil(max(v)), *[cell(d, (r, "blind"), "held-out mean") for d in (F2B, H2B) for r in T38]),
          combine(lambda v: v[0], PAPER_TABLE1_LLFF)),
    Claim("on the synthetic demo {}%: [results/demo/]", scaled(100, json_at(DEMO_HELD, "view_ber", "mean"))),
    Claim("seeds 0-2 | read blind: one held-out view fern {} / {} / {}% (p90 at most {}), horns {} / {} / {}% (p90 at most "
          "{}); one free viewpoint at most {}% (fern) and {}% (horns); Table 1 per image read blind, identity / gn / "
          "dropout / crop, seed 0: fern {} / {} / {} / {}%, horns {} / {} / {} / {}% (the paper, LLFF, blind: {} / {} / "
          "{} / {}%), every cell of the three seeds at most {}% (fern) and {}% (horns); as the owner {}% every cell; "
          "every camera together, blind: {} of 48 wrong on every run.",
          *[cell(F2B, (r, "blind"), "held-out mean") for r in T38],
          highest(*[cell(F2B, (r, "blind"), "held-out mean", 1) for r in T38]),
          *[cell(H2B, (r, "blind"), "held-out mean") for r in T38],
          highest(*[cell(H2B, (r, "blind"), "held-out mean", 1) for r in T38]),
          highest(*[cell(F2B, (r, "blind"), "free mean") for r in T38]),
          highest(*[cell(H2B, (r, "blind"), "free mean") for r in T38]),
          *table1(F2B, (T38[0],), reading="blind"), *table1(H2B, (T38[0],), reading="blind"),
          *[combine(lambda v, k=k: v[k], PAPER_TABLE1_LLFF) for k in range(4)],
          highest(*table1(F2B, T38, reading="blind")), highest(*table1(H2B, T38, reading="blind")),
          highest(*table1(F2B, T38), *table1(H2B, T38)),
          highest(*[grep(d + f"runs/{r}/all_blind.txt", r"aggregated over .*\((\d+) of 48 bits\)")
                    for d in (F2B_DIR, H2B_DIR) for r in T38])),
    Claim("at `--target_psnr 38 / 37 / 36`: blind one held-out view {} / {} / {}% (p90 {} / {} / {}), free {} / {} / {}%, "
          "as the owner {} / {} / {}%, {} / {} / {} dB from the raw renders | fern **{} / {} / {}**, horns **{} / {} / {} dB** "
          "| fern {} -> {} / {} / {}, horns {} -> {} / {} / {} |",
          *[probe(f"both_seed0_t{t}", f, BUDGET_DEMO) for f in ("held", "p90", "free", "owner held", "vs raw")
            for t in (38, 37, 36)],
          *[cell(F2B, (r, "owner"), FROM_RAW) for r in T38], *[cell(H2B, (r, "owner"), FROM_RAW) for r in T38],
          cell(F2B, (T38[0], "owner"), RAW_PSNR, 0), *[cell(F2B, (r, "owner"), RAW_PSNR, 1) for r in T38],
          cell(H2B, (T38[0], "owner"), RAW_PSNR, 0), *[cell(H2B, (r, "owner"), RAW_PSNR, 1) for r in T38]),
    Claim("(fern's seeds 1-2: {} / {}) | fern {} -> {}, horns {} -> {} |",
          cell(F2B, ("both_seed1", "owner"), FROM_RAW), cell(F2B, ("both_seed2", "owner"), FROM_RAW),
          cell(F2B, ("both_seed0", "owner"), RAW_PSNR, 0), cell(F2B, ("both_seed0", "owner"), RAW_PSNR, 1),
          cell(H2B, ("both_seed0", "owner"), RAW_PSNR, 0), cell(H2B, ("both_seed0", "owner"), RAW_PSNR, 1)),
    Claim("; horns' seeds 1-2: blind one held-out view {} / {}% (p90 {} / {}), one free viewpoint {} / {}%, as the owner "
          "at most {}% per image, {} / {} dB from the raw renders; Table 1 read blind over the three seeds: fern {}-{} / "
          "{} / {}-{} / {}-{}%, horns {}-{} / {}-{} / {}-{} / {}-{}% |",
          cell(H2B, ("both_seed1", "blind"), "held-out mean"), cell(H2B, ("both_seed2", "blind"), "held-out mean"),
          cell(H2B, ("both_seed1", "blind"), "held-out mean", 1), cell(H2B, ("both_seed2", "blind"), "held-out mean", 1),
          cell(H2B, ("both_seed1", "blind"), "free mean"), cell(H2B, ("both_seed2", "blind"), "free mean"),
          highest(*table1(H2B, ("both_seed1", "both_seed2"))),
          cell(H2B, ("both_seed1", "owner"), FROM_RAW), cell(H2B, ("both_seed2", "owner"), FROM_RAW),
          span(*[cell(F2B, (r, "blind"), ATTACKS[0]) for r in BOTH_SEEDS]),
          highest(*[cell(F2B, (r, "blind"), ATTACKS[1]) for r in BOTH_SEEDS]),
          span(*[cell(F2B, (r, "blind"), ATTACKS[2]) for r in BOTH_SEEDS]),
          span(*[cell(F2B, (r, "blind"), ATTACKS[3]) for r in BOTH_SEEDS]),
          *[span(*[cell(H2B, (r, "blind"), a) for r in BOTH_SEEDS]) for a in ATTACKS]),
    Claim("; fern's seeds 1-2: blind one held-out view {} / {}% (p90 {} / {}), one free viewpoint {} / {}%, as the owner "
          "at most {}% per image (Table 1);",
          cell(F2B, ("both_seed1", "blind"), "held-out mean"), cell(F2B, ("both_seed2", "blind"), "held-out mean"),
          cell(F2B, ("both_seed1", "blind"), "held-out mean", 1), cell(F2B, ("both_seed2", "blind"), "held-out mean", 1),
          cell(F2B, ("both_seed1", "blind"), "free mean"), cell(F2B, ("both_seed2", "blind"), "free mean"),
          highest(*table1(F2B, ("both_seed1", "both_seed2")))),
    Claim("| fern **{}**, horns **{} dB** (fern's seeds 1-2: {} / {}) |",
          cell(F2B, ("both_seed0", "owner"), FROM_RAW), cell(H2B, ("both_seed0", "owner"), FROM_RAW),
          cell(F2B, ("both_seed1", "owner"), FROM_RAW), cell(F2B, ("both_seed2", "owner"), FROM_RAW)),
    Claim("| gaussian-splats-3d {} of 6 \"present\" alone, mean {}%; PlayCanvas {} of 6, {}%; each viewer's 6 together "
          "\"present\" ({} of 48 wrong); the raw model's screenshots \"absent\" {} of 6 and {} of 6: the default's weak "
          "side, JPEG",
          shots(VIEWER_BOTH, "gs3d_wm", "present"), shots(VIEWER_BOTH, "gs3d_wm", "mean"),
          shots(VIEWER_BOTH, "playcanvas_wm", "present"), shots(VIEWER_BOTH, "playcanvas_wm", "mean"),
          highest(shots(VIEWER_BOTH, "gs3d_wm", "together"),
                  shots(VIEWER_BOTH, "playcanvas_wm", "together")),
          shots(VIEWER_BOTH, "gs3d_raw", "absent"),
          shots(VIEWER_BOTH, "playcanvas_raw", "absent")),
    Claim("| gaussian-splats-3d {} of 6 \"present\" alone, mean {}%; PlayCanvas {} of 6, {}%; each viewer's 6 together "
          "\"present\" ({} of 48 wrong at most); the raw model's screenshots \"absent\" {} of 6 and {} of 6; at 12 free viewpoints between "
          "the cameras ({} register: one close-up of a blank surface has no features) gaussian-splats-3d {} of 12 \"present\" alone, "
          "{}%, PlayCanvas {} of 12, {}%, the raw model's {} and {} \"absent\"; the held-out screenshots {} / {} dB "
          "from watergs' render under each viewer's conventions, so JPEG, not the renderer, costs most: watergs' own held-out "
          "renders at JPEG 90 read {}% a view (results/viewers/jpeg_reference/) | {} dB |",
          shots(VC33 + "default/ber.tsv", "gs3d_wm", "present"),
          shots(VC33 + "default/ber.tsv", "gs3d_wm", "mean"),
          shots(VC33 + "default/ber.tsv", "playcanvas_wm", "present"),
          shots(VC33 + "default/ber.tsv", "playcanvas_wm", "mean"),
          highest(shots(VC33 + "default/ber.tsv", "gs3d_wm", "together"),
                  shots(VC33 + "default/ber.tsv", "playcanvas_wm", "together")),
          shots(VC33 + "default/ber.tsv", "gs3d_raw", "absent"),
          shots(VC33 + "default/ber.tsv", "playcanvas_raw", "absent"),
          shots(VC33 + "default_free/ber.tsv", "gs3d_wm", "registered"),
          shots(VC33 + "default_free/ber.tsv", "gs3d_wm", "present"),
          shots(VC33 + "default_free/ber.tsv", "gs3d_wm", "mean"),
          shots(VC33 + "default_free/ber.tsv", "playcanvas_wm", "present"),
          shots(VC33 + "default_free/ber.tsv", "playcanvas_wm", "mean"),
          shots(VC33 + "default_free/ber.tsv", "gs3d_raw", "absent"),
          shots(VC33 + "default_free/ber.tsv", "playcanvas_raw", "absent"),
          grep(VC33 + "default/gap.tsv", r"^gs3d\twm\tweb\t([\d.]+)"),
          grep(VC33 + "default/gap.tsv", r"^playcanvas\twm\tplaycanvas\t([\d.]+)"),
          combine(lambda v: 100 * v[0], json_at(JPEG_REF + "default_t38_jpeg90.json", "owner", "view_ber", "mean")),
          grep(DEMO, r"watermarked vs the raw renders: ([\d.]+) dB")),
    Claim("| gaussian-splats-3d {} of 6 \"present\" alone, mean {}%; PlayCanvas {} of 6, {}%; 12 free viewpoints {} of 12 and {} of 12, "
          "{}% / {}%; watergs' own held-out renders "
          "at JPEG 90 {}% a view as the owner, {}% clean; read blind one held-out view {}%, as without the layer | {} dB |",
          shots(VC33 + "jpeg_layer/ber.tsv", "gs3d_wm", "present"),
          shots(VC33 + "jpeg_layer/ber.tsv", "gs3d_wm", "mean"),
          shots(VC33 + "jpeg_layer/ber.tsv", "playcanvas_wm", "present"),
          shots(VC33 + "jpeg_layer/ber.tsv", "playcanvas_wm", "mean"),
          shots(VC33 + "jpeg_layer_free/ber.tsv", "gs3d_wm", "present"),
          shots(VC33 + "jpeg_layer_free/ber.tsv", "playcanvas_wm", "present"),
          shots(VC33 + "jpeg_layer_free/ber.tsv", "gs3d_wm", "mean"),
          shots(VC33 + "jpeg_layer_free/ber.tsv", "playcanvas_wm", "mean"),
          scaled(100, json_at(VIEWER_T38J + "extract_jpeg90.json", "owner", "view_ber", "mean")),
          scaled(100, json_at(VIEWER_T38J + "extract_held.json", "owner", "view_ber", "mean")),
          scaled(100, json_at(VIEWER_T38J + "extract_held_blind.json", "view_ber", "mean")),
          grep(VIEWER_T38J + "eval.txt", r"watermarked vs raw renders \| ([\d.]+)")),
    Claim("the default: gaussian-splats-3d {} of 3 \"present\" alone, mean {}%; PlayCanvas {} of 3, {}%; with `--jpeg_layer 90:0.5` "
          "{} of 3 and {} of 3, {}% / {}%, each set of 3 together \"present\" ({} of 48 wrong at most); at 12 free viewpoints the "
          "default {} of 12 and {} of 12 ({}% / {}%), the JPEG layer **{} of 12 and {} of 12 ({}% / {}%)**; the raw model's "
          "\"absent\"; the screenshots {} / {} dB from watergs' render under each viewer's conventions (the demo: {} / {}), since "
          "the references follow the viewers' small-splat rules, 8-bit canvas and storage (gaussian-splats-3d's eigenvalue floor, "
          "PlayCanvas' minimum size and compact buffer, both falloffs; before those: {} / {} dB and {}% / {}% a held-out screenshot, "
          "[history](docs/history.md#real-web-viewers)) "
          "| {} / {} dB |",
          shots(VC33 + "fern_t38/ber.tsv", "gs3d_wm", "present"),
          shots(VC33 + "fern_t38/ber.tsv", "gs3d_wm", "mean"),
          shots(VC33 + "fern_t38/ber.tsv", "playcanvas_wm", "present"),
          shots(VC33 + "fern_t38/ber.tsv", "playcanvas_wm", "mean"),
          shots(VC33 + "fern_t38j/ber.tsv", "gs3d_wm", "present"),
          shots(VC33 + "fern_t38j/ber.tsv", "playcanvas_wm", "present"),
          shots(VC33 + "fern_t38j/ber.tsv", "gs3d_wm", "mean"),
          shots(VC33 + "fern_t38j/ber.tsv", "playcanvas_wm", "mean"),
          highest(shots(VC33 + "fern_t38j/ber.tsv", "gs3d_wm", "together"),
                  shots(VC33 + "fern_t38j/ber.tsv", "playcanvas_wm", "together")),
          *[shots(d + "ber.tsv", v + "_wm", field) for d in (VC33 + "fern_t38_free/", VC33 + "fern_t38j_free/")
            for field in ("present", "mean") for v in ("gs3d", "playcanvas")],
          grep(VC33 + "fern_t38/gap.tsv", r"^gs3d\twm\tweb\t([\d.]+)"),
          grep(VC33 + "fern_t38/gap.tsv", r"^playcanvas\twm\tplaycanvas\t([\d.]+)"),
          grep(VC33 + "default/gap.tsv", r"^gs3d\twm\tweb\t([\d.]+)"),
          grep(VC33 + "default/gap.tsv", r"^playcanvas\twm\tplaycanvas\t([\d.]+)"),
          grep(FERN_T38_S31 + "gap.tsv", r"^gs3d\twm\tweb\t([\d.]+)"),
          grep(FERN_T38_S31 + "gap.tsv", r"^playcanvas\twm\tplaycanvas\t([\d.]+)"),
          shots(FERN_T38_S31 + "ber.tsv", "gs3d_wm", "mean"),
          shots(FERN_T38_S31 + "ber.tsv", "playcanvas_wm", "mean"),
          cell(F2B, (T38[0], "owner"), FROM_RAW), cell(F2B, ("both_seed0_t38j", "owner"), FROM_RAW)),
    Claim("the demo: gaussian-splats-3d {} of 6 \"present\" alone, mean {}%; PlayCanvas {} of 6, {}%; 12 free viewpoints ({} "
          "register) {} and {}, {}% / {}%; fern: {} of 3 and {} of 3, {}% / {}%, 12 free viewpoints {} and {}, {}% / {}%; the raw "
          "models' screenshots \"absent\" alone, {} of {}; gaussian-splats-3d's screen recording of the demo ({} frames, H.264 at {} kbit/s) "
          "\"present\" from frame {}, {} of {} frames alone, the raw model's \"absent\"; the price is the blind reading: one held-out view read blind {}% (demo), "
          "{}% (fern) | demo **{}**, fern **{} dB** | {} -> {}, {} -> {} |",
          *[shots(JLS + "demo_first_jl90x05/viewers_held/ber.tsv", v + "_wm", f)
            for v, f in (("gs3d", "present"), ("gs3d", "mean"), ("playcanvas", "present"), ("playcanvas", "mean"))],
          shots(JLS + "demo_first_jl90x05/viewers_free/ber.tsv", "gs3d_wm", "registered"),
          *[shots(JLS + "demo_first_jl90x05/viewers_free/ber.tsv", v + "_wm", f)
            for f in ("present", "mean") for v in ("gs3d", "playcanvas")],
          *[shots(JLS + "fern_first_jl90x05/" + views + "/ber.tsv", v + "_wm", f)
            for views in ("viewers_held", "viewers_free") for f in ("present", "mean") for v in ("gs3d", "playcanvas")],
          combine(sum, *[shots(JLS + run + views + "/ber.tsv", v + "_raw", "absent")
                         for run in ("demo_first_jl90x05/", "fern_first_jl90x05/") for views in ("viewers_held", "viewers_free")
                         for v in ("gs3d", "playcanvas")]),
          combine(sum, *[shots(JLS + run + views + "/ber.tsv", v + "_raw", "registered")
                         for run in ("demo_first_jl90x05/", "fern_first_jl90x05/") for views in ("viewers_held", "viewers_free")
                         for v in ("gs3d", "playcanvas")]),
          grep(JLS + "demo_first_jl90x05/recording/recording.tsv", r"^gs3d_wm\t\d+\t\d+ of (\d+)"), grep(JLS + "demo_first_jl90x05/recording/recording.tsv", r"^gs3d_wm\t(\d+)"),
          grep(JLS + "demo_first_jl90x05/recording/recording.tsv", r"^gs3d_wm\t(?:[^\t]*\t){6}(\d+)"), grep(JLS + "demo_first_jl90x05/recording/recording.tsv", r"^gs3d_wm\t(?:[^\t]*\t){4}(\d+) /"),
          grep(JLS + "demo_first_jl90x05/recording/recording.tsv", r"^gs3d_wm\t\d+\t\d+ of (\d+)"),
          *blind_and_costs("first_jl90x05", "owner_seed0_jl05", "demo_first_jl90x05")),
    Claim("the demo: held-out {}% / {}% ({} of 6 and {} of 6 \"present\" alone), 12 free viewpoints {}% / {}% ({} of {} each), "
          "but at less fidelity than the default keeps; fern: {}% / {}% ({} of 3 each), free {}% / {}% ({} of 12 each); the blind reading kept: one "
          "held-out view {}% (demo), {}% (fern) | demo {}, fern {} dB | {} -> {}, {} -> {} |",
          *[shots(JLS + "demo_jl90x1_it3000/viewers_held/ber.tsv", v + "_wm", "mean") for v in ("gs3d", "playcanvas")],
          *[shots(JLS + "demo_jl90x1_it3000/viewers_held/ber.tsv", v + "_wm", "present") for v in ("gs3d", "playcanvas")],
          *[shots(JLS + "demo_jl90x1_it3000/viewers_free/ber.tsv", v + "_wm", "mean") for v in ("gs3d", "playcanvas")],
          lowest(*[shots(JLS + "demo_jl90x1_it3000/viewers_free/ber.tsv", v + "_wm", "present") for v in ("gs3d", "playcanvas")]),
          shots(JLS + "demo_jl90x1_it3000/viewers_free/ber.tsv", "gs3d_wm", "registered"),
          *[shots(JLS + "fern_jl90x1_it3000/viewers_held/ber.tsv", v + "_wm", "mean") for v in ("gs3d", "playcanvas")],
          lowest(*[shots(JLS + "fern_jl90x1_it3000/viewers_held/ber.tsv", v + "_wm", "present") for v in ("gs3d", "playcanvas")]),
          *[shots(JLS + "fern_jl90x1_it3000/viewers_free/ber.tsv", v + "_wm", "mean") for v in ("gs3d", "playcanvas")],
          lowest(*[shots(JLS + "fern_jl90x1_it3000/viewers_free/ber.tsv", v + "_wm", "present") for v in ("gs3d", "playcanvas")]),
          *blind_and_costs("jl90x1_it3000", "both_seed0_jl3000", "demo_jl90x1_it3000")),
    Claim("\"present\" from frame {}; {} of {} frames \"present\" alone (mean {}% a frame), all together {} of 48 wrong, \"present\"; "
          "the raw model's recording \"absent\" ({} of 48); `detect` {} s a frame: H.264 takes more of the default's finer "
          "band than of the first default's | {} dB |",
          grep(RECORDING_T38, r"^gs3d_wm\t(?:[^\t]*\t){6}(\d+)"), grep(RECORDING_T38, r"^gs3d_wm\t(?:[^\t]*\t){4}(\d+) /"),
          grep(RECORDING_T38, r"^gs3d_wm\t\d+\t\d+ of (\d+)"), grep(RECORDING_T38, r"^gs3d_wm\t(?:[^\t]*\t){3}([\d.]+)%"),
          grep(RECORDING_T38, r"^gs3d_wm\t(?:[^\t]*\t){5}\w+ \((\d+) of 48\)"),
          grep(RECORDING_T38, r"^gs3d_raw\t(?:[^\t]*\t){5}\w+ \((\d+) of 48\)"),
          grep("results/viewers/default_t38/recording/detect_gs3d_wm.txt", r"over 33 images \(([\d.]+) s an image\)"),
          grep(DEMO, r"watermarked vs the raw renders: ([\d.]+) dB")),
    Claim("the default's weak side, JPEG ([history](docs/history.md#the-default-serves-both-readers)) | {} dB |",
          grep(DEMO_S29, r"watermarked vs the raw renders: ([\d.]+) dB")),
    Claim("| as the owner {} / {} / {}% per held-out view / 48 free viewpoints {} / {} / {}%; read blind (without the raw model): "
          "the 48 cameras together {} of 48 wrong on each seed (\"present\"), one held-out view alone {}-{}% | **{} / {} / {} dB** | "
          "{} -> {} / {} / {} |",
          *[probe(l, "owner held", BOTH) for l in BOTH_R2P2], *[probe(l, "free48", BOTH) for l in BOTH_R2P2],
          highest(*[grep(f"results/reading_both/runs/{l}/all48.txt", r"aggregated over the 48 views .*\((\d+) of 48 bits\)")
                    for l in BOTH_R2P2]),
          span(*[probe(l, "held", BOTH) for l in BOTH_R2P2]), *[probe(l, "vs raw", BOTH) for l in BOTH_R2P2],
          grep("results/blind_designs/raw_train.log", r"^train: held-out views \(6\): PSNR ([\d.]+)"),
          *[probe(l, "PSNR", BOTH) for l in BOTH_R2P2]),
    Claim("| fern: the default {}% / {}% a view (gaussian-splats-3d / PlayCanvas), with `--jpeg_layer 90:0.5` {}% / {}%; the demo: "
          "{}% / {}%, with the layer {}% / {}% | fern {} / {}, demo {} / {} dB |",
          *[curve(f, c) for f in ("fern default", "fern jpeg_layer 90/0.5", "demo default", "demo jpeg_layer 90/0.5")
            for c in ("web", "playcanvas")],
          cell(F2B, (T38[0], "owner"), FROM_RAW), cell(F2B, ("both_seed0_t38j", "owner"), FROM_RAW),
          grep(DEMO, r"watermarked vs the raw renders: ([\d.]+) dB"),
          grep(VIEWER_T38J + "eval.txt", r"watermarked vs raw renders \| ([\d.]+)")),
    Claim("{} times faster than brute force on {}k points, {} threads (`point_init_benchmark`",
          grep("results/benchmarks/point_init.txt", r"^threads 2: .* speed-up (\d+)x wall"),
          grep("results/benchmarks/point_init.txt", r"^points: (\d+)000,"),
          grep("results/benchmarks/point_init.txt", r"^threads (2):")),
]


# ---- The check. --------------------------------------------------------------------------------

def _context(text, start, end):
    """Where a figure's file must be named: its table row, or its paragraph and the one before."""
    line_start = text.rfind("\n", 0, start) + 1
    line_end = text.find("\n", end)
    line_end = len(text) if line_end < 0 else line_end
    if text[line_start:line_end].startswith("|"):
        return text[line_start:line_end]
    para_start = text.rfind("\n\n", 0, start)
    para_start = text.rfind("\n\n", 0, para_start) if para_start > 0 else 0
    para_end = text.find("\n\n", end)
    return text[max(para_start, 0):len(text) if para_end < 0 else para_end]


def _named(path, context):
    """The file, or a folder above it (results/x/ or results/x), is named in the context (a file
    outside the repository, such as the paper's source: the word NAMED_AS gives it)."""
    if path in NAMED_AS:
        return re.search(NAMED_AS[path], context) is not None
    parts = path.split("/")
    candidates = ["/".join(parts[:i]) for i in range(2, len(parts) + 1)]
    return any(re.search(re.escape(c) + r"(/|\b)", context) for c in candidates)


def _rounding(figure):
    decimals = len(figure.split(".")[1]) if "." in figure else 0
    return 0.5 * 10 ** -decimals + 1e-9


def _one_line(text):
    return " ".join(text.split())


def _check_claim(claim, readme, root):
    files = ", ".join(claim.files())
    m = claim.pattern().search(readme)
    if not m:
        label = claim.name or claim.phrase.replace("{}", "N")
        return [f'README figure "{_one_line(label)}" not found in the README (its file: {files})']
    shown = _one_line(m.group(0))
    context = _context(readme, m.start(), m.end())
    problems = [f'README figure "{shown}": its file {f} is not named beside it'
                for f in claim.files() if not _named(f, context)]
    try:
        expected = [v for s in claim.sources for v in s.values(root)]
    except LookupError as e:
        return problems + [f'README figure "{shown}": {e}']
    figures = m.groups()
    if len(expected) != len(figures):
        return problems + [f'README figure "{shown}": {len(figures)} figures in the README, '
                           f'{len(expected)} read from {files}']
    for figure, value in zip(figures, expected):
        tol = claim.tol if claim.tol is not None else _rounding(figure)
        if abs(float(figure.replace(",", "")) - value) > tol:
            problems.append(f'README figure "{shown}" does not match {files}: README {figure}, '
                            f'file {value:.6g} (tolerance {tol:.3g})')
    return problems


def _check_lines(block, readme, root):
    start = readme.find(block.first_line)
    if start < 0:
        return [f'README block "{block.first_line}" not found in the README (its file: {block.path})']
    end = readme.find("```", start)
    try:
        lines = {block.normalize(line.rstrip()) for line in _text(root, block.path).splitlines()}
    except LookupError as e:
        return [f'README block "{block.first_line}": {e}']
    problems = []
    if not _named(block.path, _context(readme, start, start)):
        problems.append(f'README block "{block.first_line}": its file {block.path} is not named beside it')
    for line in readme[start:end].rstrip("\n").splitlines():
        if block.normalize(line.rstrip()) not in lines:
            problems.append(f'README figure "{_one_line(line)}" is not a line of {block.path}')
    return problems


def check(readme, root, claims=None):
    """One line per problem, in the manifest's order; empty when every figure matches its file."""
    problems = []
    for claim in CLAIMS if claims is None else claims:
        if isinstance(claim, Lines):
            problems += _check_lines(claim, readme, root)
        else:
            problems += _check_claim(claim, readme, root)
    return problems


# ---- What no claim covers. ------------------------------------------------------------------------
#
# `uncovered` lists every number of the README that is neither inside a claim's phrase nor one of
# the skips below; what it lists is a measured figure still to tie to its file (or a setting still
# to add to SETTINGS). The rule, applied in this order:
#   1. fenced blocks are skipped whole (the two install commands, the layout); a fenced block that
#      holds figures (the demo's summary) is a Lines claim and so covered;
#   2. inline code (`...`), link targets ("](...)") and paths (a word with a "/") are skipped: commands,
#      flag values, attack names (`gn:0.01`), files and commit-named folders;
#   3. a number glued to a letter is part of a name or a unit, not a figure: 3D, 3DGS, H200, SH0,
#      WGS-26, JPEG-90, 504x378, 100k, a commit such as 4b15521 (a trailing "x" alone, as in "39x",
#      is a ratio and stays);
#   4. a number inside one of the SETTINGS phrases (every occurrence): what a run was asked to do
#      or a fixed fact of the method or a package (48 bits, 2,000 iterations, seeds 0-2, 2 cores,
#      COLMAP 3.8), not what it measured.

SETTINGS = [
    # the method, the scenes and what a run was asked to do
    "{}-bit message", "{} bits", "{} views", "{} cameras", "The {} held-out views", "{} free viewpoints",
    "{} iterations", "seeds {}-{}", "seed {}", "{} draws", "{} crops", "p <= {}", "{} camera models",
    "(c + {}, r + {})", "{} px", "at {} MP", "-j{}", "{}-core", "Table {}", "(raw >= {} dB)", "(goal: {} min, {} GiB)",
    "to {} renders of the raw model", "per {}-Gaussian", "{}-nearest-neighbour", "{} of the same photos",
    "take {} s or more", "pool {} decoder", "sit above {} dB from the raw model's", "down to {} dB from", "until session {}",
    "its floor {} (", "at under {}%", "real JPEG {}", "at its {} held-out cameras", "the default's {} (", "--target_psnr {}",
    # the machine
    "{} cores",
    # versions of packages and formats
    "COLMAP {}", "`colmap` {}", "OpenCV {}", "Ceres {}", "Eigen {}", "clang {}", "cuDNN {}", "OpenSplat {}",
    "(versions {}-{})", "version {}", "SH {}", "Mip-NeRF {}",
]


def _skipped(readme):
    """(start, end) spans of rules 1-3 of `uncovered`."""
    spans = [m.span() for m in re.finditer(r"^```.*?^```", readme, re.M | re.S)]  # 1. fenced blocks
    spans += [m.span() for m in re.finditer(r"`[^`\n]*`", readme)]  # 2. inline code
    spans += [m.span() for m in re.finditer(r"\]\([^)\s]*\)", readme)]  # link targets
    spans += [m.span() for m in re.finditer(r"[\w.-]*/[\w./#*-]*", readme)]  # paths
    return spans


def uncovered(readme, claims=None):
    """(line number, number) for each number of the README that no claim covers and that the rule
    above does not skip: the measured figures the manifest does not check yet."""
    spans = _skipped(readme)
    for claim in CLAIMS if claims is None else claims:
        if isinstance(claim, Lines):
            start = readme.find(claim.first_line)
            if start >= 0:
                spans.append((start, readme.find("```", start)))
            continue
        m = claim.pattern().search(readme)
        if m:
            spans.append((m.start(), m.end()))
    for phrase in SETTINGS:  # 4. every occurrence of a setting
        for m in Claim(phrase).pattern().finditer(readme):
            spans += [m.span(g) for g in range(1, len(m.groups()) + 1)]
    found = []
    for m in re.finditer(r"\d[\d,]*(?:\.\d+)?", readme):
        number = m.group(0).rstrip(",")
        before = readme[m.start() - 1:m.start()]
        after = readme[m.start() + len(number):m.start() + len(number) + 2]
        if any(a <= m.start() < b for a, b in spans):
            continue
        glued_after = after[:1].isalpha() and not (after[:1] == "x" and not after[1:2].isalnum())
        glued_before = before.isalpha() or before == "_" or (before == "-" and
                                                               readme[m.start() - 2:m.start() - 1].isalpha())
        if glued_after or glued_before:  # 3. part of a name or a unit
            continue
        found.append((readme.count("\n", 0, m.start()) + 1, number))
    return found


if __name__ == "__main__":
    import sys
    with open(sys.argv[1] if len(sys.argv) > 1 else "README.md", encoding="utf-8") as f:
        for line, number in uncovered(f.read()):
            print(f"{line}: {number}")
