"""`harness bench intervals`: does the tables' 95 % interval cover the true mean at the views a study has?

Simulated paired differences with a known mean μ = 0.5: n values per replicate (default n = 8, the
default study's held-out views; also 4 and 12), ``--reps`` replicates per distribution (seeded, so
the numbers are reproducible), for

* ``normal``  N(μ, 1);
* ``t3``      μ + Student-t with 3 degrees of freedom (heavy tails);
* ``skewed``  μ + (lognormal(0, 0.5) − e^{1/8}) (mean 0, moderate right skew, skewness 1.75);
* ``very skewed`` μ + (lognormal(0, 1) − e^{1/2}) (skewness 6.2, like a few views where a pruned set
  loses a visible object: no interval built from 8 values covers that well).

Coverage = the share of replicates whose interval contains μ, for the house interval (Student t,
:func:`harness.report.stats.t_ci`), the percentile bootstrap the tables used before
(:func:`harness.report.stats.bootstrap_ci`: 10,000 resamples, seed 0) and scipy's BCa bootstrap
(10,000 resamples, on the first ``--bca-reps`` replicates: it is ~100× slower). The binomial standard
error of a coverage near 0.95 over R replicates is √(0.95·0.05/R) (0.0034 at R = 4,000). Also the
mean width relative to the t interval's. Writes ``results/bench/intervals.md`` / ``.json``.
"""

from __future__ import annotations

import numpy as np

NAME = "intervals"
HELP = "coverage of the tables' 95 % interval vs the percentile bootstrap on simulated paired data (n = 8)"
MU = 0.5
DISTRIBUTIONS = ("normal", "t3", "skewed", "very skewed")


def add_arguments(parser) -> None:
    parser.add_argument("--n", default="4,8,12", help="values per replicate (comma-separated; default 4,8,12)")
    parser.add_argument("--reps", type=int, default=4000, help="replicates per distribution and n")
    parser.add_argument("--bca-reps", type=int, default=500, help="replicates for scipy's BCa (slow)")
    parser.add_argument("--seed", type=int, default=2026)


def draw(dist: str, rng: np.random.Generator, size) -> np.ndarray:
    """Paired differences with mean :data:`MU` from ``dist``."""
    if dist == "normal":
        return MU + rng.standard_normal(size)
    if dist == "t3":
        return MU + rng.standard_t(3, size)
    if dist == "skewed":
        return MU + rng.lognormal(0.0, 0.5, size) - np.exp(0.125)
    if dist == "very skewed":
        return MU + rng.lognormal(0.0, 1.0, size) - np.exp(0.5)
    raise ValueError(f"unknown distribution {dist!r}; known: {', '.join(DISTRIBUTIONS)}")


def coverage(dist: str, n: int, reps: int, bca_reps: int, seed: int) -> dict:
    """Coverage and mean width of each interval on ``reps`` replicates of ``n`` values."""
    from scipy import stats as sst

    from harness.report import stats

    x = draw(dist, np.random.default_rng([seed, n, DISTRIBUTIONS.index(dist)]), (reps, n))
    out = {}
    for name, fn, k in (("t", stats.t_ci, reps), ("percentile bootstrap", stats.bootstrap_ci, reps),
                        ("BCa bootstrap", None, min(bca_reps, reps))):
        if fn is None:
            def fn(v):
                ci = sst.bootstrap((v,), np.mean, method="BCa", n_resamples=stats.N_RESAMPLES,
                                   rng=np.random.default_rng(stats.SEED)).confidence_interval
                return ci.low, ci.high
        if k == 0:
            continue
        ci = np.array([fn(v) for v in x[:k]])
        out[name] = {"coverage": float(np.mean((ci[:, 0] <= MU) & (MU <= ci[:, 1]))), "reps": int(k),
                     "mean_width": float(np.mean(ci[:, 1] - ci[:, 0]))}
    return out


def _markdown(rows: list[dict]) -> str:
    lines = ["# Coverage of 95 % intervals of a mean paired difference (`harness bench intervals`)", "",
             f"Simulated paired differences with known mean {MU}; coverage = share of replicates whose "
             "interval contains it (nominal 0.95; binomial SE ≈ 0.0034 at 4,000 replicates, 0.0097 at 500). "
             "Width relative to the t interval's in brackets.", "",
             "| distribution | n | t interval (house) | percentile bootstrap (before) | BCa bootstrap |",
             "|---|---|---|---|---|"]
    for r in rows:
        t = r["t"]["mean_width"]
        cells = [f"{r[k]['coverage']:.3f} ({r[k]['reps']} reps, width ×{r[k]['mean_width'] / t:.2f})"
                 if k in r else "–" for k in ("t", "percentile bootstrap", "BCa bootstrap")]
        lines.append(f"| {r['distribution']} | {r['n']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.core.errors import InputError

    folder = out_dir(args)  # created and probed before any work
    try:
        ns = [int(v) for v in args.n.split(",") if v.strip()]
    except ValueError:
        raise InputError("--n", f"expected comma-separated integers, got {args.n!r}") from None
    if not ns or min(ns) < 2 or args.reps < 1 or args.bca_reps < 0:
        raise InputError("--n", "needs n >= 2 values per replicate and --reps >= 1")
    rows = []
    for dist in DISTRIBUTIONS:
        for n in ns:
            rows.append({"distribution": dist, "n": n, **coverage(dist, n, args.reps, args.bca_reps, args.seed)})
            print(f"{dist} n={n}: " + ", ".join(f"{k} {v['coverage']:.3f}" for k, v in rows[-1].items()
                                                 if isinstance(v, dict)), flush=True)
    md = _markdown(rows)
    path = write_result(NAME, {"mu": MU, "seed": args.seed, "rows": rows}, md, out=folder)
    print(md)
    print(f"written {path}")
    return 0
