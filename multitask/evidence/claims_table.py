"""The claims table as files: ``claims.csv`` (every column of ``claims.COLUMNS``), ``claims.tex``
(booktabs, a ``table*`` at text width for a two-column paper) and ``claims_config.json`` (the
statistics' settings)."""
from __future__ import annotations

import re
from dataclasses import asdict
from pathlib import Path

import pandas as pd

from rnn_seg.runs.folder import write_atomic, write_json

from .claims import FRAME_ACCURACY_MARGIN, MIN_PAIRS, Claim, evaluate
from .latex import escape, number, requires
from .paired import UNIT_OF_PAIRING, BootstrapConfig, ConfigId
from .tables import METRIC_LABELS
from ..models.variants import get_variant

_WEIGHTING_MARKS = {"fixed": "1", "gradnorm": r"\alpha"}
_PREFIXES = {"original": r"orig.\ ", "forward": r"fwd.\ "}
_COLUMN_SPEC = "@{\\extracolsep{\\fill}}llcrrcrcl@{}"
_NUMBER_OF_COLUMNS = 9


def write_claims(runs: pd.DataFrame, out: Path,
                 config: BootstrapConfig = BootstrapConfig(),
                 claims: tuple[Claim, ...] | None = None, budget: str = "") -> list[Path]:
    """Evaluate the claims on ``runs`` and write the three files into ``out``.

    Args:
        runs: one row per finished run (``collect.run_rows``).
        out: the folder written into.
        config: bootstrap settings of every comparison.
        claims: the claims to test; None = the paper's (``claims.CLAIMS``).
        budget: the runs' data and budget, ending the LaTeX caption
            (``captions.RunsDescription.sentence``); empty = not stated.

    Returns:
        The paths of ``claims.csv``, ``claims.tex`` and ``claims_config.json``.
    """
    table = evaluate(runs, claims, config)
    paths = [out / "claims.csv", out / "claims.tex", out / "claims_config.json"]
    write_atomic(paths[0], table.to_csv(index=False, float_format="%.4f"))
    write_atomic(paths[1], claims_latex(table, config, budget))
    write_json(paths[2], {"bootstrap": asdict(config), "ci_method": config.method,
                          "test": "two-sided Wilcoxon signed-rank over folds, zero differences "
                                  "discarded, exact / exhaustive permutation for n <= 13",
                          "unit_of_pairing": UNIT_OF_PAIRING, "min_pairs_for_verdict": MIN_PAIRS,
                          "frame_accuracy_margin": FRAME_ACCURACY_MARGIN})
    return paths


def claims_latex(table: pd.DataFrame, config: BootstrapConfig = BootstrapConfig(),
                 budget: str = "") -> str:
    """``table`` (``claims.evaluate``) as a booktabs ``table*``: the claims grouped under the
    paper's words, one line per comparison and score; the caption ends with ``budget``."""
    lines = [r"% The paper's claims tested on our runs (multitask-tables, claims.csv).",
             requires("booktabs").rstrip("\n"),
             r"\begin{table*}[t]", r"\centering", r"\footnotesize", r"\setlength{\tabcolsep}{4pt}",
             rf"\caption{{{_caption(table, config, budget)}}}", r"\label{tab:claims}",
             rf"\begin{{tabular*}}{{\textwidth}}{{{_COLUMN_SPEC}}}", r"\toprule",
             rf"Comparison & Score & Expected & Paper & Ours & {_level(config)} CI & $p$ & "
             r"Folds$\times$seeds & Verdict \\", r"\midrule"]
    quote = None
    for row in table.itertuples(index=False):
        if row.quote != quote:
            if quote is not None:
                lines.append(r"\addlinespace")
            quote = row.quote
            lines.append(rf"\multicolumn{{{_NUMBER_OF_COLUMNS}}}{{@{{}}p{{0.98\textwidth}}}}"
                         rf"{{\emph{{``{escape(quote)}''}}}} \\")
        lines.append(" & ".join(_cells(row)) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular*}", r"\end{table*}"]
    return "\n".join(lines) + "\n"


def _cells(row) -> list[str]:
    tested = not pd.isna(row.ours_diff)
    ci = (rf"[{number(row.ci_low)}, {number(row.ci_high)}]"
          if tested and not pd.isna(row.ci_low) else "--")
    return [_comparison(row.comparison), METRIC_LABELS.get(row.metric, escape(row.metric)),
            _direction(row.direction),
            number(row.paper_diff, signed=True),
            number(row.ours_diff, signed=True), ci,
            f"{row.p_value:.3f}" if tested else "--",
            rf"{row.folds}$\times${row.seeds}" if tested else "--",
            "not run" if not tested else "--" if pd.isna(row.verdict) else row.verdict]


def _caption(table: pd.DataFrame, config: BootstrapConfig, budget: str) -> str:
    """What is compared and how, the verdicts' rules, and ``budget``. Claims without a published
    difference (the conjecture on another task) leave out what describes the paper's tables."""
    folds, seeds = table.folds.dropna(), table.seeds.dropna()
    spread = ("" if folds.empty else
              f" over {_span(folds)} LOUO folds, {_span(seeds)} seed(s) per model and fold")
    published = table.paper_diff.notna().any()
    subject = ("The paper's claims" if published
               else "The paper's conjecture (no published result)")
    paper_column = " Paper: the same difference in the paper's tables." if published else ""
    return (
        f"{subject} tested on our runs. Differences in percentage points: the mean of "
        f"per-fold paired differences{spread} (seeds averaged within a fold).{paper_column} "
        f"{_level(config)} CI: {config.method}, "
        f"{config.resamples} resamples, seed {config.seed}; $p$: two-sided Wilcoxon signed-rank "
        "test over folds. Verdicts: reproduced (expected sign, CI excludes 0), consistent "
        "(expected sign, CI includes 0), not reproduced (opposite sign, CI includes 0), "
        "contradicted (opposite sign, CI excludes 0); for $|\\Delta| \\le$ margin, the same "
        "with the CI inside / outside the margin; none below "
        f"{MIN_PAIRS} folds. Subscripts $1$: $w_1{{=}}w_2{{=}}1$, $\\alpha$: GradNorm "
        "$\\alpha{=}1.5$; $g$(X) = X$_\\alpha$ $-$ X$_1$; orig.: original labels; fwd.: "
        "forward LSTM."
        + (" ``Best'': ours against our strongest other model, the paper's against its "
           "runner-up. The paper's Tables II and III baselines are DiPietro et al.'s published "
           "numbers." if published else "")
        + (f" {budget}" if budget else ""))


def _level(config: BootstrapConfig) -> str:
    return f"{config.confidence * 100:g}\\,\\%"


def _span(values: pd.Series) -> str:
    low, high = int(values.min()), int(values.max())
    return f"{low}" if low == high else f"{low}--{high}"


def _comparison(text: str) -> str:
    """``(APr-gradnorm - APr-fixed) - original/A-fixed`` -> ``$g$(APr) $-$ orig.\\ A``."""
    text = _GAIN.sub(r"g:\1", text)
    latex = [r"$-$" if t == "-" else _gain(t) if t.startswith("g:") else _config(t)
             for t in text.split()]
    return " ".join(latex)


_GAIN = re.compile(r"\((\S+)-gradnorm - \1-fixed\)")


def _gain(token: str) -> str:
    return f"$g$({_config(token.removeprefix('g:') + '-fixed', weighting=False)})"


def _config(label: str, weighting: bool = True) -> str:
    """``original/APc-fixed`` -> ``orig.\\ APc$_1$``; single-task models carry no weighting."""
    config = ConfigId.parse(label)
    prefix = "".join(_PREFIXES.get(p, "") for p in (config.annotations, config.direction))
    shown = weighting and get_variant(config.variant).multitask
    mark = rf"$_{{{_WEIGHTING_MARKS[config.weighting]}}}$" if shown else ""
    return f"{prefix}{config.variant}{mark}"


def _direction(text: str) -> str:
    """``> 0 (lower is better)`` -> ``$>0$``; ``|diff| <= 1`` -> ``$|\\Delta| \\le 1$``."""
    text = text.replace(" (lower is better)", "").replace("|diff| <=", r"|\Delta| \le")
    return f"${text}$"
