"""Every claim of the paper the ``claims`` table tests: its words, where they are, its type and band.

Each :class:`Claim` quotes the paper verbatim (``quote``: a substring of its LaTeX source, so the
test ``tests/test_claim_citations.py`` finds it), cites the lines it is read from (``lines``: the
sentence, and the table rows its numbers come from), lists the numbers it takes from them
(``numbers``: each appears within ±2 lines of a cited line), and has a **type** read from its
wording (:data:`harness.study.rules.TYPES`; ``reason`` quotes the words that make it that type).

Bands (the paper's number each is read from):

* competitive at 10 % and 20 %: BetaDesc − the best camera-aware method > −5.15 dB — the largest
  deficit the paper's own Table 1 calls competitive (cinema, mid: 26.34 vs 31.49);
* better at 30 % on large scenes: > 0 (direction) and > +0.525 dB (size: half of breakfast's +1.05,
  the smaller of the two effects the paper reports; cinema +1.80), on scenes of ≥ :data:`LARGE_SPLATS`;
* Table 2: > 0 for every comparison; Beta's effect sizes (with descriptors +7.19 / +16.53 / +7.71 /
  +3.32, without +4.32 / +8.92 / +5.39 / +3.32 dB) give the size bands +1.66 dB;
* Table 3: descriptors help at keep 0.7 / 0.5 / 0.3 (+1.63 / +0.89 / +1.02 dB): direction > 0 and
  size > half the row's effect; the gap is modest: |Δ| < 1.6 dB at every keep; monotonic: each step
  > 0; SSIM at keep 0.3 > 0.87 (a level: comparable only at the paper's 1024 px);
* sensitivity: presets within ±0.18 dB (not testable: the paper gives values for one preset of four),
  voxel 0.20 and 0.30 against 0.10 × the diagonal within ±0.20 dB (the paper's own spread), and the
  same for 2 and 3 % against the default 1 %;
* runtime (``results/bench/overhead.json``): overhead ≤ 16 % (twice the paper's ≈ 8 %) and added
  time ≤ 1.0 s per scene (twice its ≈ 0.5 s), both as averages over the benchmark's scenes.
"""

from __future__ import annotations

from dataclasses import dataclass

from harness.study.rules import AVERAGE, EFFECT, EQUIVALENCE, EXISTENCE, INF, UNIVERSAL

#: "large scenes" of the Table 1 high-ratio claim: at least this many splats (the paper's breakfast
#: and cinema are room-scale captures; of the public scenes only bonsai-7k qualifies)
LARGE_SPLATS = 1_000_000
#: the paper's render size (L305: "at 1024 px longest side"); an absolute level measured at another
#: size is not comparable with the paper's
PAPER_LONGEST_SIDE = 1024
#: the scenes the pre-registered reading selections chose on (ctc_configs/study/reading.yaml, reading2.yaml):
#: marked † in every claims table — what was tuned there is optimistically biased there
SELECTION_SCENES = ("bonsai-7k-mini", "luigi")


@dataclass(frozen=True)
class Claim:
    """One claim: ``what`` it measures (the recipe :mod:`harness.study.verdicts` evaluates) and how
    the paper states it. ``unit`` is ``universal`` or ``average`` for an effect-size claim (how each
    of its two verdicts is reached); ``smallest``: the smallest effect the paper reports for it."""

    key: str
    title: str
    type: str
    reason: str
    quote: str
    lines: tuple[int, ...]
    numbers: tuple[str, ...]
    paper: str
    at: str
    band: tuple[float, float]
    what: tuple
    unit: str = ""
    smallest: float = 0.0
    digits: int = 2
    untestable: str = ""


L323 = ("However, the proposed camera-agnostic approach remains competitive without access to image "
        "projections.")
L323_HIGH = "At high pruning ratios, our method achieves slightly better performance on"
L384_DESC = "Across all evaluated datasets, descriptor-based neighbourhood modelling improves pruning stability"
L384_BETA = "Incorporating Beta evidence modelling further enhances robustness"
L384_BEST = "The full method consistently achieves the best reconstruction quality"
L442_MONO = "Quality degradation across pruning ratios is monotonic and gradual."
L442_SSIM = "SSIM remains above $0.87$ even at $70\\%$ removal"
L442_GAP = "the descriptor performance gap remains modest even at extreme pruning ($\\lesssim 1.6$\\,dB PSNR"
L442_WHICH = "confirming that descriptor-driven pruning selects \\emph{which} splats to remove more intelligently"
L464_AVG = "the average performance difference between with and without descriptors remains modest (within $1.6$"
L464_HET = "per-scene analysis of the $14$-scene evaluation set reveals heterogeneous behavior"
PRESETS_UNTESTABLE = ("the paper names flat, opacity-heavy and structure-heavy without values; ours are our "
                      "own (methods/betadesc/evidence.py), so their spread says nothing about the paper's")
TABLE3 = {0.7: ("1.63", 453, ("37.38", "35.75", "1.63")), 0.5: ("0.89", 454, ("33.68", "32.79", "0.89")),
          0.3: ("1.02", 455, ("29.07", "28.05", "1.02"))}


def _t3(keep: float) -> Claim:
    effect, line, numbers = TABLE3[keep]
    return Claim(
        f"t3-keep-{keep:g}", "Table 3: descriptors help", EFFECT,
        f"a stated magnitude: ΔPSNR {effect} dB, a mean over the 14 scenes (the table's caption)",
        L442_WHICH, (442, line), numbers, f"+{effect} dB (14-scene mean)", f"keep {keep:g}", (0.0, INF),
        ("gain", (keep,)), unit=AVERAGE, smallest=float(effect))


CLAIMS: tuple[Claim, ...] = (
    Claim("t1-competitive-10%", "Table 1: competitive with camera-aware pruning", UNIVERSAL,
          "shown row by row (\"on four MPEG CTC scenes\"): competitive on each scene", L323, (323, 362),
          ("26.34", "31.49"), "deficit to the best camera-aware method 0.34–2.99 dB at 10 %, 0.12–5.15 at 20 %",
          "prune 10%", (-5.15, INF), ("best-camera", 0.1)),
    Claim("t1-competitive-20%", "Table 1: competitive with camera-aware pruning", UNIVERSAL,
          "shown row by row (\"on four MPEG CTC scenes\"): competitive on each scene", L323, (323, 362),
          ("26.34", "31.49"), "deficit to the best camera-aware method 0.12–5.15 dB at 20 % (its 4 scenes)",
          "prune 20%", (-5.15, INF), ("best-camera", 0.2)),
    Claim("t1-large-high", "Table 1: better than camera-aware at high ratios on large scenes", EFFECT,
          "a magnitude per named scene (\"on breakfast (tracked) and cinema (tracked)\"): each large scene",
          L323_HIGH, (323, 356, 362), ("26.12", "25.07", "24.92", "23.12"),
          "+1.05 (breakfast), +1.80 dB (cinema) over the best camera-aware", "prune 30%", (0.0, INF),
          ("best-camera-large", 0.3), unit=UNIVERSAL, smallest=1.05),
    Claim("t2-best", "Table 2: the full method is best in every row", UNIVERSAL,
          "\"consistently\", \"Bold marks the best value per row\"", L384_BEST, (384, 403, 409, 415, 421, 429),
          ("31.07", "29.23", "34.47", "28.90", "27.16", "27.15", "38.05"),
          "full − best ablation +1.84 / +5.57 / +0.01 / 0.00 dB", "prune 20%", (0.0, INF), ("best", 0.2)),
    Claim("t2-descriptors", "Table 2: descriptors help", UNIVERSAL, "\"Across all evaluated datasets\"",
          L384_DESC, (384, 403, 409, 415, 421), ("31.07", "29.23", "34.47", "28.90"),
          "+1.84 / +5.57 / +0.01 / 0.00 dB", "prune 20%", (0.0, INF), ("pair", 0.2, "full", "nodesc")),
    Claim("t2-beta", "Table 2: Beta evidence helps, with descriptors", EFFECT,
          "a magnitude per dataset row (Table 2): every row", L384_BETA, (384, 403, 409, 415, 421),
          ("31.07", "23.88", "34.47", "17.94", "27.16", "19.45", "38.05", "34.73"),
          "+7.19 / +16.53 / +7.71 / +3.32 dB", "prune 20%", (0.0, INF), ("pair", 0.2, "full", "nobeta"),
          unit=UNIVERSAL, smallest=3.32),
    Claim("t2-beta-nodesc", "Table 2: Beta evidence helps, without descriptors", EFFECT,
          "a magnitude per dataset row (Table 2): every row", L384_BETA, (384, 403, 409, 415, 421),
          ("29.23", "24.91", "28.90", "19.98", "27.15", "21.76", "38.05", "34.73"),
          "+4.32 / +8.92 / +5.39 / +3.32 dB", "prune 20%", (0.0, INF), ("pair", 0.2, "nodesc", "neither"),
          unit=UNIVERSAL, smallest=3.32),
    _t3(0.7), _t3(0.5), _t3(0.3),
    Claim("t3-gap", "Table 3: the descriptor gap stays modest, within 1.6 dB either way", EQUIVALENCE,
          "\"the average performance difference … within 1.6 dB PSNR across all tests\": a band both ways, "
          "on the mean, at every keep", L464_AVG, (442, 464), ("1.6",), "+1.63 / +0.89 / +1.02 dB; ≲ 1.6 dB",
          "keep 0.7 / 0.5 / 0.3", (-1.6, 1.6), ("gain", (0.7, 0.5, 0.3))),
    Claim("t3-monotonic", "Table 3: quality degrades monotonically with pruning", UNIVERSAL,
          "a property of every degradation curve (\"monotonic\"): every scene, every step", L442_MONO,
          (442, 453, 454, 455), ("37.38", "33.68", "29.07"), "37.38 > 33.68 > 29.07 dB (keep 0.7 / 0.5 / 0.3)",
          "keep 0.7 → 0.5 → 0.3", (0.0, INF), ("monotonic",)),
    Claim("t3-ssim", "Table 3: SSIM stays above 0.87 at 70 % removal", AVERAGE,
          "a level of the 14-scene mean (Table 3: 0.882)", L442_SSIM, (442, 455), ("0.87", "0.882"),
          "0.882 (14-scene mean, 1024 px)", "keep 0.3", (0.87, INF), ("level", 0.3, "ssim"), digits=3),
    Claim("heterogeneity", "Per-scene heterogeneity: descriptors help on some scenes, hurt on others", EXISTENCE,
          "\"heterogeneous behavior\": a gain on some scene and a loss on another", L464_HET, (464,),
          ("4.04", "12.4"), "+4.04 (solo_tango_male) … −12.4 dB (flowerdance) at 70 % pruning", "keep 0.3",
          (0.0, INF), ("gain", (0.3,))),
    Claim("presets", "Sensitivity: coefficient presets spread ≤ 0.18 dB PSNR", EQUIVALENCE,
          "\"This narrow spread\" of 5-scene means: a band both ways", "PSNR result ranges across presets span",
          (468,), ("36.26", "36.44", "0.18"), "36.26–36.44 dB (5-scene means)", "keep 0.7", (-0.18, 0.18),
          ("sweep", "preset", None, ("flat", "opacity-heavy", "structure-heavy")), untestable=PRESETS_UNTESTABLE),
    Claim("voxel-literal", "Sensitivity: voxel 0.10 / 0.20 / 0.30 × diagonal is flat", EQUIVALENCE,
          "\"flat PSNR results\" of 5-scene means: a band both ways", "yields flat PSNR results of",
          (470,), ("0.10", "0.20", "0.30", "36.24", "36.34", "36.14"), "36.24 / 36.34 / 36.14 dB (spread 0.20)",
          "keep 0.7", (-0.2, 0.2), ("sweep", "voxel", 0.1, (0.2, 0.3))),
    Claim("voxel-percent", "Sensitivity: voxel 1 / 2 / 3 % of the diagonal is flat (L470's flatness around "
          "L313's 1–2 %)", EQUIVALENCE, "\"flat PSNR results\" of 5-scene means: a band both ways",
          "yields flat PSNR results of", (470,), ("36.24", "36.34", "36.14"), "spread 0.20 dB (L470)", "keep 0.7",
          (-0.2, 0.2), ("sweep", "voxel", 0.01, (0.02, 0.03))),
    Claim("runtime-relative", "Runtime: descriptors add ≈ 8 %", AVERAGE,
          "\"averages … per scene\": a mean over scenes", "representing only $\\sim 8\\%$ computational overhead",
          (474,), ("6.78", "7.29", "8"), "7.29 vs 6.78 s per scene, ≈ 8 %", "end-to-end prune, one thread",
          (-INF, 16.0), ("bench", "overhead_pct"), digits=1),
    Claim("runtime-added", "Runtime: descriptors add ≈ 0.5 s per scene", AVERAGE,
          "\"adds approximately 0.5 s per scene\": a mean over scenes", "The descriptor aggregation adds approximately",
          (474,), ("0.5",), "+0.5 s per scene", "end-to-end prune, one thread", (-INF, 1.0), ("bench", "added_s"),
          digits=3),
)
