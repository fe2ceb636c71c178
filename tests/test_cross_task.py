"""The JIGSAWS tasks side by side (``multitask-tables tasks``,
``multitask.evidence.studies.tasks``): read from each task's tables."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from multitask.evidence.cli import main as tables_main
from multitask.evidence.studies.tasks import MODELS, SCORES


def _tables(folder: Path, shift: float, seeds: int) -> Path:
    """A task's summary.csv (A's means) and claims.csv (each model minus A), values from
    ``shift``."""
    folder.mkdir(parents=True)
    pd.DataFrame([{"annotations": "revised", "direction": "bidirectional", "variant": "A",
                   "weighting": "fixed", "folds": 7,
                   **{f"{s}_mean": 80 + shift + k for k, s in enumerate(SCORES)}}]
                 ).to_csv(folder / "summary.csv", index=False)
    pd.DataFrame([{"comparison": f"{m} - A-fixed", "metric": s, "ours_diff": shift + i,
                   "ci_low": shift + i - 1, "ci_high": shift + i + 1, "verdict": "inconclusive",
                   "folds": 7, "seeds": seeds}
                  for i, m in enumerate(MODELS) for s in SCORES]).to_csv(folder / "claims.csv",
                                                                        index=False)
    return folder


def test_each_task_keeps_the_numbers_of_its_own_tables(tmp_path):
    one, two = _tables(tmp_path / "one", 1.0, 3), _tables(tmp_path / "two", -2.0, 1)
    assert tables_main(["tasks", f"Suturing={one}", f"Needle_Passing={two}",
                        "--out", str(tmp_path / "out")]) == 0
    table = pd.read_csv(tmp_path / "out" / "tasks.csv")
    assert list(dict.fromkeys(table.task)) == ["Suturing", "Needle_Passing"]
    a = table[(table.task == "Needle_Passing") & (table.model == "A")]
    assert a.set_index("score").value.to_dict() == {s: 78.0 + k for k, s in enumerate(SCORES)}
    apoc = table[(table.task == "Suturing") & (table.model == "APoc-gradnorm - A")]
    assert (apoc.value == 1.0 + MODELS.index("APoc-gradnorm")).all() and (apoc.seeds == 3).all()
    text = (tmp_path / "out" / "tasks.md").read_text()
    assert "| Needle Passing | A | 78.0 | 79.0 | 80.0 | 7 x 1 |" in text
    assert text.count("\n") == 2 + 2 * (1 + len(MODELS))


def test_a_task_without_a_contrast_is_one_line_naming_its_file(tmp_path, capsys):
    folder = _tables(tmp_path / "one", 0.0, 1)
    claims = pd.read_csv(folder / "claims.csv")
    claims[claims.comparison != "APc-fixed - A-fixed"].to_csv(folder / "claims.csv", index=False)
    assert tables_main(["tasks", f"Knot_Tying={folder}", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(folder / "claims.csv") in err and "APc-fixed" in err
    assert not (tmp_path / "out").exists()
