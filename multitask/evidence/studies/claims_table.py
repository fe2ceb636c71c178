"""The claims table as files: ``claims.csv`` (every column of ``claims.COLUMNS``), ``claims.tex``
(booktabs ``table*`` floats at text width for a two-column paper, each at most a page high,
under a short caption), ``claims_note.tex`` (the method, the verdicts' rules and the
abbreviations: a paragraph to include beneath the table or in an appendix, where a caption of
13 lines held them) and ``claims_config.json`` (the statistics' settings)."""
from __future__ import annotations

import re
from dataclasses import asdict
from pathlib import Path

import pandas as pd

from rnn_seg.runs.folder import write_atomic, write_json

from ...models.variants import get_variant
from ..render import drawing
from ..render.latex import escape, number, requires
from ..render.tables import METRIC_LABELS
from ..runs.pooling import architecture_name
from ..statistics.paired import MAX_EXACT_FOLDS, UNIT_OF_PAIRING, ConfigId, StatsConfig
from .claims import (FRAME_ACCURACY_MARGIN, MIN_PAIRS, POWER_DECIMALS, Claim, evaluate,
                     smallest_adjusted_p)

_WEIGHTING_MARKS = {"fixed": "1", "gradnorm": r"\alpha"}
_PREFIXES = {"original": r"orig.\ ", "forward": r"fwd.\ "}
_COLUMN_SPEC = "@{\\extracolsep{\\fill}}llcrrcrrccl@{}"
_NUMBER_OF_COLUMNS = 11
#: Rows of one float: a family's claims plus two for its quote; families are not split, and a
#: float of at most this many fits an IEEE page's text height with its caption.
ROWS_PER_FLOAT = 40
#: The task's letter of ``tables.METRIC_LABELS`` -> the claims table's prefix: gesture scores are
#: the plain names ("Edit", so they cannot be read as model A's), progress scores say so.
_TASK_PREFIXES = {"A": "", "P": "Progress "}


def write_claims(runs: pd.DataFrame, out: Path, config: StatsConfig = StatsConfig(),
                 claims: tuple[Claim, ...] | None = None, budget: str = "") -> list[Path]:
    """Evaluate the claims on ``runs`` and write the four files into ``out``.

    Args:
        runs: one row per finished run (``collect.run_rows``).
        out: the folder written into.
        config: the test's level and the power simulation's settings.
        claims: the claims to test; None = the paper's (``claims.CLAIMS``).
        budget: the runs' data and budget, ending the LaTeX caption
            (``captions.RunsDescription.sentence``); empty = not stated.

    Returns:
        The paths of ``claims.csv``, ``claims.tex``, ``claims_note.tex`` and
        ``claims_config.json``.
    """
    drawing.say("testing the paper's claims (paired tests, power simulations)")
    table = evaluate(runs, claims, config)
    agreed = {claim.agreed for claim in claims or ()} or {"reproduced"}
    paths = [out / "claims.csv", out / "claims.tex", out / "claims_note.tex",
             out / "claims_config.json"]
    write_atomic(paths[0], table.to_csv(index=False, float_format="%.4f"))
    write_atomic(paths[1], claims_latex(table, config, budget))
    write_atomic(paths[2], claims_note(table, config, " / ".join(sorted(agreed))))
    write_json(paths[3], {
        "statistics": asdict(config), "method": config.method,
        "test": "two-sided exact sign-flip test of the mean per-fold difference, every one of the "
                f"2^n sign vectors (n <= {MAX_EXACT_FOLDS}); interval: the shifts it does not "
                "reject",
        "families": f"the claims of one quoted sentence{_and_score(table)} (claim id prefix); "
                    "Holm within each, over its declared size (claims not tested count as p = 1)",
        "power": "probability of the claimed verdict before the family's correction, fold "
                 "differences normal with the paper's mean and our sd; simulated once per number "
                 f"of folds, reported to {POWER_DECIMALS} decimals",
        "power_monte_carlo_error_max": round(config.power_error, 6),
        "unit_of_pairing": UNIT_OF_PAIRING, "min_pairs_for_verdict": MIN_PAIRS,
        "frame_accuracy_margin": FRAME_ACCURACY_MARGIN})
    return paths


def claims_latex(table: pd.DataFrame, config: StatsConfig = StatsConfig(),
                 budget: str = "") -> str:
    """``table`` (``claims.evaluate``) as booktabs ``table*`` floats: the claims grouped under the
    paper's words, one line per comparison and score; whole families, at most
    ``ROWS_PER_FLOAT`` rows a float; the first float's caption ends with ``budget``, the others
    continue it."""
    lines = [r"% The paper's claims tested on our runs (multitask-tables, claims.csv).",
             requires("booktabs").rstrip("\n")]
    for k, families in enumerate(_floats(table)):
        caption = (_caption(table, config, budget) if k == 0 else
                   r"The paper's claims tested on our runs, continued from "
                   r"Table~\ref{tab:claims}.")
        lines += [r"\begin{table*}[t]", r"\centering", r"\footnotesize",
                  r"\setlength{\tabcolsep}{3pt}", rf"\caption{{{caption}}}",
                  r"\label{tab:claims}" if k == 0 else rf"\label{{tab:claims:{k + 1}}}",
                  rf"\begin{{tabular*}}{{\textwidth}}{{{_COLUMN_SPEC}}}", r"\toprule",
                  rf"Comparison & Score & Claim & Paper & Ours & {_level(config)} CI & $p$ & "
                  r"$p_\mathrm{Holm}$ & Folds & Power & Verdict \\", r"\midrule"]
        for i, family in enumerate(families):
            lines += [r"\addlinespace"] * bool(i) + [
                rf"\multicolumn{{{_NUMBER_OF_COLUMNS}}}{{@{{}}p{{0.98\textwidth}}}}"
                rf"{{\emph{{``{escape(family.quote.iloc[0])}''}}}} \\"]
            lines += [" & ".join(_cells(row)) + r" \\" for row in family.itertuples(index=False)]
        lines += [r"\bottomrule", r"\end{tabular*}", r"\end{table*}"]
    return "\n".join(lines) + "\n"


def _floats(table: pd.DataFrame) -> list[list[pd.DataFrame]]:
    """The families of ``table`` in order, packed into floats of at most ``ROWS_PER_FLOAT``
    rows (a family larger than that gets a float of its own)."""
    floats, rows = [[]], 0
    for _, family in table.groupby("family", sort=False):
        size = len(family) + 2
        if floats[-1] and rows + size > ROWS_PER_FLOAT:
            floats.append([])
            rows = 0
        floats[-1].append(family)
        rows += size
    return floats


def _cells(row) -> list[str]:
    tested = not pd.isna(row.ours_diff)
    margin = _margin(row.direction)
    paper = number(row.paper_diff, signed=True)
    if not pd.isna(row.paper_in_ci) and not row.paper_in_ci:
        paper += r"$^\ast$"
    ci = (rf"[{_bound(row.ci_low, margin)}, {_bound(row.ci_high, margin)}]"
          if tested else "--")
    return [_comparison(row.comparison), score_label(row.metric), _direction(row.direction),
            paper, number(row.ours_diff, digits=2, signed=True), ci,
            f"{row.p_value:.3f}" if tested else "--",
            f"{row.p_adjusted:.3f}" if tested else "--",
            row.folds_favouring if tested else "--",
            "--" if pd.isna(row.power_at_paper_effect)
            else f"{row.power_at_paper_effect:.{POWER_DECIMALS}f}",
            "not run" if not tested else "--" if pd.isna(row.verdict) else row.verdict]


def score_label(metric: str) -> str:
    """``gesture_edit`` -> ``Edit``, ``progress_edit`` -> ``Progress Edit`` (``tables``'
    ``A Edit`` would read as model A's)."""
    if metric not in METRIC_LABELS:
        return escape(metric)
    letter, name = METRIC_LABELS[metric].split(" ", 1)
    return _TASK_PREFIXES.get(letter, f"{letter} ") + name


def _margin(direction: str) -> float:
    """The equivalence margin a ``direction`` text names (``|diff| <= 1``), else 0."""
    match = re.fullmatch(r"\|diff\| <= (\S+)", direction)
    return float(match.group(1)) if match else 0.0


def _bound(value: float, margin: float = 0.0) -> str:
    """An interval end with 2 decimals, or as many more as it takes (up to 6) for it not to
    print as 0 or as the margin when it is not: a rounded bound never contradicts the verdict."""
    if pd.isna(value):
        return "--"
    if abs(value) == float("inf"):
        return r"$-\infty$" if value < 0 else r"$\infty$"
    digits = 2
    while digits < 6 and any(round(value, digits) == t != value for t in (0.0, margin, -margin)):
        digits += 1
    return number(value, digits=digits, signed=True)


def _caption(table: pd.DataFrame, config: StatsConfig, budget: str) -> str:
    """What is compared, in two sentences, and ``budget`` (plain text, escaped here); the method
    is in ``claims_note``."""
    spread = _spread(table)
    return (f"{_subject(table)} tested on our runs, {_families(table)}: mean "
            f"per-fold paired differences in percentage points{spread}, exact sign-flip tests, "
            "Holm's correction within each family. Method, verdicts and abbreviations: the "
            "note to this table." + (f" {escape(budget)}" if budget else ""))


def _spread(table: pd.DataFrame) -> str:
    """`` over 8 LOUO folds, 3 seed(s) per model and fold``, empty without folds."""
    folds, seeds = table.folds.dropna(), table.seeds.dropna()
    return ("" if folds.empty else
            f" over {_span(folds)} LOUO folds, {_span(seeds)} seed(s) per model and fold")


def _families(table: pd.DataFrame) -> str:
    """How the claims form families, for the caption and the note."""
    return f"one family per quoted sentence{_and_score(table)}"


def _and_score(table: pd.DataFrame) -> str:
    """`` and score`` where a sentence's claims are split into one family per score (the TCN
    conjecture's, ``claims.TCN_CLAIMS``), else empty."""
    return " and score" if table.family.nunique() > table.quote.nunique() else ""


def _subject(table: pd.DataFrame) -> str:
    return ("The paper's claims" if table.paper_diff.notna().any()
            else "The paper's conjecture (no published result)")


def claims_note(table: pd.DataFrame, config: StatsConfig = StatsConfig(),
                agreed: str = "reproduced") -> str:
    """``claims_note.tex``: how Table~\\ref{tab:claims} (``claims_latex``) was computed and read,
    as one paragraph; claims without a published difference (the conjecture on another task or
    architecture) leave out what describes the paper's tables and say what the expected sign is.
    ``agreed``: the verdict of a claim the test agrees with (``claims.Claim.agreed``)."""
    spread = _spread(table)
    published = table.paper_diff.notna().any()
    paper_column = (" Paper: the same difference in the paper's tables, $^\\ast$ where it lies "
                    "outside our interval." if published else "")
    power = (" Power: the probability of the claimed verdict before the correction if the fold "
             "differences were normal with the paper's mean and our standard deviation."
             if published else "")
    alpha = f"{config.alpha:g}"
    limits = _limits(table, config)
    conjecture = agreed == "supported"
    expected = ("" if not conjecture else " Claim: the sign the paper's conjecture expects, a gain "
                "($>0$, or the margin); the paper reports no such result, so no verdict rests on "
                "a published difference.")
    backbones = sorted({ConfigId.parse(side).architecture for comparison in table.comparison
                        for side in comparison.replace("(", "").replace(")", "").split(" - ")}
                       - {""})
    backbone_note = (" " + ", ".join(escape(architecture_name(b)) for b in backbones)
                     + ": the backbone, its runs from its own grid, paired only with runs of the "
                     "same backbone." if backbones else "")
    return (
        "% The method of the claims table (claims.tex, multitask-tables): \\input this file "
        "beneath the table or in an appendix.\n"
        f"\\noindent\\textbf{{Notes to Table~\\ref{{tab:claims}}.}} {_subject(table)} tested "
        f"on our runs, {_families(table)}. Differences in "
        f"percentage points: the mean of per-fold paired differences{spread} (seeds averaged "
        f"within a fold).{paper_column}{expected} {_level(config)} CI and $p$: the exact "
        "sign-flip test over all $2^n$ sign vectors of the $n$ folds, and the interval that inverts it (it "
        f"excludes 0 exactly when $p \\le {alpha}$); $p_\\mathrm{{Holm}}$: Holm's correction "
        "within the family, over all its claims (a claim not tested counts as $p = 1$). "
        f"Verdict: {agreed} / contradicted when $p_\\mathrm{{Holm}} \\le "
        f"{alpha}$ with the claimed / the opposite sign, inconclusive otherwise"
        + (" (neither shown, which is no evidence of equality)" if conjecture else "") + "; for "
        f"$|\\Delta| \\le$ margin, $p$ of the hypothesis our mean lies against ({agreed}: the "
        "CI lies inside the margin; contradicted: beyond it); none below "
        f"{MIN_PAIRS} folds.{limits} Folds: folds with the claimed sign (within the "
        f"margin).{power} Subscripts $1$: $w_1{{=}}w_2{{=}}1$, $\\alpha$: GradNorm "
        "$\\alpha{=}1.5$; $g$(X) = X$_\\alpha$ $-$ X$_1$; $r$(X) = X $-$ orig.\\ X; orig.: "
        "original labels; fwd.: forward LSTM." + backbone_note
        + (" ``Best'': ours against our strongest other model, the paper's against its "
           "runner-up. The paper's Tables II and III baselines are DiPietro et al.'s published "
           "numbers." if published else "") + "\n")


def _limits(table: pd.DataFrame, config: StatsConfig) -> str:
    """A sentence naming the families too large for any verdict but inconclusive, if any."""
    tested = table[table.p_value.notna()]
    blocked = [(family, len(rows), int(rows.folds.max()))
               for family, rows in tested.groupby("family", sort=False)
               if smallest_adjusted_p(len(rows), int(rows.folds.max())) > config.alpha]
    if not blocked:
        return ""
    named = ", ".join(f"{escape(family)} ({m} claims, {n} folds: "
                      f"{smallest_adjusted_p(m, n):.3f})" for family, m, n in blocked)
    return (f" No $p_\\mathrm{{Holm}}$ can be below $m \\cdot 2/2^n$ for a family of $m$ claims; "
            f"above {config.alpha:g} for {named}, which are inconclusive whatever the data.")


def _level(config: StatsConfig) -> str:
    return f"{config.confidence * 100:g}\\,\\%"


def _span(values: pd.Series) -> str:
    low, high = int(values.min()), int(values.max())
    return f"{low}" if low == high else f"{low}--{high}"


def _comparison(text: str) -> str:
    """``(APr-gradnorm - APr-fixed) - original/A-fixed`` -> ``$g$(APr) $-$ orig.\\ A``;
    ``(APoc-fixed - original/APoc-fixed) - (...)`` -> ``$r$(APoc$_1$) $-$ ...``."""
    text = _RELABEL.sub(r"r:\1", _GAIN.sub(r"g:\1", text))
    latex = [r"$-$" if t == "-" else _gain(t) if t.startswith(("g:", "r:")) else _config(t)
             for t in text.split()]
    return " ".join(latex)


_GAIN = re.compile(r"\((\S+)-gradnorm - \1-fixed\)")
_RELABEL = re.compile(r"\((\S+) - original/\1\)")


def _gain(token: str) -> str:
    """``g:APr`` -> ``$g$(APr)``, ``r:APoc-fixed`` -> ``$r$(APoc$_1$)``."""
    kind, name = token.split(":", 1)
    if kind == "g":
        return f"$g$({_config(name + '-fixed', weighting=False)})"
    return f"$r$({_config(name)})"


def _config(label: str, weighting: bool = True) -> str:
    """``original/APc-fixed`` -> ``orig.\\ APc$_1$``; single-task models carry no weighting."""
    config = ConfigId.parse(label)
    prefix = "".join(_PREFIXES.get(p, "") for p in (config.annotations, config.direction))
    if config.architecture:
        prefix = rf"{escape(architecture_name(config.architecture))}\ {prefix}"
    shown = weighting and get_variant(config.variant).multitask
    mark = rf"$_{{{_WEIGHTING_MARKS[config.weighting]}}}$" if shown else ""
    return f"{prefix}{config.variant}{mark}"


def _direction(text: str) -> str:
    """``> 0 (lower is better)`` -> ``$>0$``; ``|diff| <= 1`` -> ``$|\\Delta| \\le 1$``."""
    text = text.replace(" (lower is better)", "").replace("|diff| <=", r"|\Delta| \le")
    return f"${text}$"
