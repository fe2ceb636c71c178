"""Coverage of the claims' 95 % interval (the inverted exact sign-flip test, ``multitask.evidence
.paired``) against the paired t interval, at 8 and 7 folds, by simulation: fold differences drawn
from a normal, a heavy-tailed (t with 3 degrees of freedom) and two skewed distributions, each
centred on a true difference of 0; the share of intervals holding it, and their mean width.
docs/REPRODUCTION.md ("Paired statistics") quotes the numbers.

    python bench/interval_coverage.py [--reps 20000]
"""
from __future__ import annotations

import argparse

import numpy as np
from scipy import stats

from multitask.evidence.statistics.paired import SignFlip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=20_000, help="simulated data sets per case")
    reps = parser.parse_args().reps
    rng = np.random.default_rng(2026)
    shapes = {"normal": lambda n: rng.normal(0, 1, n),
              "t, 3 df (heavy tails)": lambda n: rng.standard_t(3, n),
              "exponential - 1 (skewed)": lambda n: rng.exponential(1, n) - 1,
              "lognormal(0, 1) - e^0.5 (skewed)": lambda n: rng.lognormal(0, 1, n) - np.exp(0.5)}
    print(f"{reps} data sets per row; coverage (mean width) of the 95 % intervals")
    for n in (8, 7):
        quantile = stats.t.ppf(0.975, n - 1)
        for name, draw in shapes.items():
            flip, t = np.zeros(2), np.zeros(2)
            for _ in range(reps):
                d = draw(n)
                low, high = SignFlip(d).interval()
                flip += (low <= 0 <= high, high - low)
                half = quantile * d.std(ddof=1) / np.sqrt(n)
                t += (abs(d.mean()) <= half, 2 * half)
            flip, t = flip / reps, t / reps
            print(f"{n} folds, {name:34s} sign-flip {flip[0]:.3f} ({flip[1]:.2f})   "
                  f"t {t[0]:.3f} ({t[1]:.2f})")


if __name__ == "__main__":
    main()
