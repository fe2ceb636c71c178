"""Figures: one colour per class in ribbons and legends (read back from the pixels), time in
seconds, per-gesture error bars with absent and never-recognised gestures told apart, the example
trial chosen, training curves from history.csv."""
from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.container import ErrorbarContainer  # noqa: E402

from jigsaws_tools.plots import (Ribbon, class_colours, draw_ribbon,  # noqa: E402
                                 layout_with_legends, task_colours)
from multitask.evidence.cli import main as tables_main  # noqa: E402
from multitask.evidence.render import curves, figures  # noqa: E402
from multitask.evidence.runs.collect import per_fold, run_rows  # noqa: E402
from multitask.grid.spec import Experiment  # noqa: E402
from tests.fake_grid import (ABSENT, FOLDS, GESTURES, NEVER_RECOGNISED,  # noqa: E402
                             write_fake_grid)

SECONDS_PER_CLASS = 2.0


@pytest.fixture(scope="module")
def grid(tmp_path_factory, synth_dir):
    return write_fake_grid(tmp_path_factory.mktemp("grid"), data=synth_dir)


@pytest.fixture()
def captured(monkeypatch):
    """The figures ``multitask.evidence.render.figures.save`` is given, by file name, instead of
    files."""
    shown: dict[str, plt.Figure] = {}

    def keep(fig, out_dir, name):
        shown[name] = fig
        return [out_dir / f"{name}.png"]
    monkeypatch.setattr(figures, "save", keep)
    monkeypatch.setattr(curves, "save", keep)
    yield shown
    plt.close("all")


def _pixel(buffer: np.ndarray, fig: plt.Figure, x: float, y: float) -> np.ndarray:
    """RGB at display coordinates (x, y) of a drawn figure (origin bottom left)."""
    return buffer[int(fig.bbox.height - y), int(x), :3].astype(int)


@pytest.mark.parametrize("classes,ordered", [(5, True), (10, False), (6, False), (15, False)])
def test_ribbon_and_legend_show_each_class_in_one_colour(classes, ordered):
    names = tuple(f"C{k}" for k in range(classes))
    colours = task_colours(classes, ordered)
    labels = np.repeat(np.arange(classes), 10)
    ribbon = Ribbon("row", labels, np.arange(len(labels)) / 5.0, names, colours)
    fig, ax = plt.subplots(figsize=(10, 1.5))
    draw_ribbon(ax, ribbon)
    layout_with_legends(fig, [ribbon])
    fig.canvas.draw()
    buffer = np.asarray(fig.canvas.buffer_rgba())
    expected = np.round(colours[:, :3] * 255).astype(int)
    for k in range(classes):                      # left quarter of each run: no class name there
        x, y = ax.transData.transform((k * SECONDS_PER_CLASS + 0.3, 0.2))
        assert np.abs(_pixel(buffer, fig, x, y) - expected[k]).max() <= 2, f"ribbon class {k}"
    legend = fig.legends[0]
    for k, handle in enumerate(legend.legend_handles):
        box = handle.get_window_extent()
        centre = ((box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2)
        assert np.abs(_pixel(buffer, fig, *centre) - expected[k]).max() <= 2, f"legend {k}"
    plt.close(fig)


def test_stage_colours_span_the_map_and_qualitative_maps_are_not_stretched():
    stages = class_colours(5, "viridis")
    assert np.allclose(stages[-1], matplotlib.colormaps["viridis"](1.0))
    assert np.allclose(class_colours(6)[:, :3], matplotlib.colormaps["tab10"].colors[:6])
    with pytest.raises(ValueError, match="Set2 has 8 colours for 10 classes"):
        class_colours(10, "Set2")


@pytest.mark.slow
def test_per_gesture_accuracy_has_error_bars_and_tells_absent_from_never_recognised(
        grid, captured):
    folds = per_fold(run_rows(grid)[0])
    figures.per_gesture_accuracy(folds, GESTURES, grid / "figures")
    ax = captured["per_gesture_accuracy"].axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == [
        f"{g}\n0 of {len(FOLDS)}\nfolds" if g in ABSENT else g for g in GESTURES]
    assert ax.get_title() == ""
    bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert len(bars) == 3
    ends = np.concatenate([np.concatenate(c.lines[2][0].get_segments()) for c in bars])
    assert ends[:, 1].min() >= 0 and ends[:, 1].max() <= 100       # clipped to [0, 100]
    a = folds[(folds.variant == "A") & (folds.annotations == "revised")
              & (folds.direction == "bidirectional")]
    heights = [p.get_height() for p in ax.containers[1].patches]      # model A's bars
    expected = a[[f"gesture_accuracy_{g}" for g in GESTURES]].mean().fillna(0.0)
    np.testing.assert_allclose(heights, expected.to_numpy())
    marks = [t.get_text() for t in ax.texts]
    assert marks.count("n/a") == 3 * len(ABSENT) and marks.count("0") == 3
    assert NEVER_RECOGNISED in GESTURES


def test_example_figures_take_the_chosen_trial_and_show_seconds(grid, captured):
    folds = per_fold(run_rows(grid)[0])
    choice = figures.example_trial(grid, folds, "Suturing_D003")
    assert choice == ("Suturing_D003", "D")
    example = figures.example_truth(grid, *choice)
    figures.all_figures(grid, folds, grid / "figures", example)
    segmentation = captured["segmentation_example"]
    assert "Suturing_D003" in segmentation.axes[0].get_title()
    assert segmentation.axes[-1].get_xlabel() == "time [s]"
    end = segmentation.axes[-1].get_xlim()[1]                   # the last sample's end
    assert end == pytest.approx((example.truth.frames[-1] - 1 + 6) / 30)
    progress = captured["progress_example"].axes[0]
    assert "Suturing_D003" in progress.get_legend().get_title().get_text()
    assert any("APr" in t.get_text() for t in progress.get_legend().get_texts())
    assert figures.example_trial(grid, folds) == ("Suturing_B001", "B")
    with pytest.raises(ValueError, match="Suturing_Z001.*Suturing_B001"):
        figures.example_trial(grid, folds, "Suturing_Z001")


def test_fold_letters_label_the_points_apart_and_a_stands_beside_apoc(grid, captured):
    folds = per_fold(run_rows(grid)[0])
    figures.fold_accuracy(folds, grid / "figures")
    figures.gesture_vs_progress(folds, grid / "figures")
    (per_model,), (scatter,) = captured["fold_accuracy"].axes, captured["gesture_vs_progress"].axes
    assert [t.get_text() for t in per_model.get_xticklabels()] == sorted(FOLDS)
    assert [t.get_text() for t in per_model.get_legend().get_texts()][0] == "A"
    assert sorted(t.get_text() for t in scatter.texts) == sorted(FOLDS)
    assert min(t.get_fontsize() for t in scatter.texts) >= 8
    _assert_labels_clear(scatter)


@pytest.mark.parametrize("points", [
    {"B": (85.0, 87.9), "I": (84.7, 87.85), "F": (88.2, 89.1), "E": (89.0, 89.3),
     "G": (81.7, 87.7), "C": (91.0, 91.5), "H": (89.8, 93.8), "D": (72.0, 81.9)},   # real grid's
    {f: (80 + 0.05 * k, 80 + 0.05 * k) for k, f in enumerate(FOLDS)},              # a clump
])
def test_fold_labels_overlap_no_point_and_no_other_label(points):
    fig, ax = plt.subplots(figsize=(3.5, 2.9))
    x, y = (np.array([p[i] for p in points.values()]) for i in (0, 1))
    ax.scatter(x, y, s=figures.MARKER_PT ** 2)
    ax.set_xlim(*figures._padded(x))
    ax.set_ylim(*figures._padded(y))
    fig.tight_layout()
    figures._label_points(ax, x, y, list(points), figures.MARKER_PT)
    assert sorted(t.get_text() for t in ax.texts) == sorted(points)
    if len(set(np.round(x))) > 1:                 # points far enough apart for every near place
        assert not any(t.arrow_patch for t in ax.texts)
    _assert_labels_clear(ax)


def _assert_labels_clear(ax: plt.Axes) -> None:
    """No label of ``ax`` overlaps another label or a marker of its scatter plot, and each lies
    inside the axes."""
    fig = ax.figure
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    frame = ax.get_window_extent(renderer)
    radius = figures.MARKER_PT / 2 * fig.dpi / 72
    markers = ax.transData.transform(ax.collections[0].get_offsets())
    for k, box in enumerate(boxes):
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 <= box.y1 <= frame.y1
        assert not any(box.overlaps(other) for other in boxes[k + 1:]), ax.texts[k].get_text()
        for mx, my in markers:
            assert not (box.x0 < mx + radius and mx - radius < box.x1
                        and box.y0 < my + radius and my - radius < box.y1), ax.texts[k].get_text()


def test_gradnorm_panels_in_the_paper_order_on_one_epoch_axis(grid, captured):
    figures.gradnorm_weights(grid, grid / "figures")
    axes = captured["gradnorm_weights"].axes
    variants = [ax.get_title().split()[0] for ax in axes]
    assert variants == [v for v in figures.GRADNORM_ORDER if v in variants] and variants
    assert len({ax.get_xlim() for ax in axes}) == 1


@pytest.mark.filterwarnings("ignore:More than 20 figures")
@pytest.mark.slow
def test_training_curves_one_figure_per_configuration_a_line_per_run(grid, captured):
    curves.training_curves(grid, grid / "curves")
    assert len(captured) == 22
    fig = captured["revised-bidirectional-APoc-gradnorm"]
    titles = [ax.get_title() for ax in fig.axes]
    assert titles == ["gesture loss", "progress loss", "gesture test accuracy [%]",
                      "progress test accuracy [%]"]
    history = pd.read_csv(next(grid.glob(
        "runs/revised/bidirectional/APoc-gradnorm/seed0/B/history.csv")))
    lines = fig.axes[2].get_lines()
    assert len(lines) == len(FOLDS) * 2                        # one per run: 8 folds x 2 seeds
    scored = history.n[history.test_gesture_acc.notna()].to_numpy()
    np.testing.assert_array_equal(lines[0].get_xdata(), scored)
    assert fig.axes[0].get_xlabel() == "epoch"


@pytest.mark.slow
def test_tables_command_draws_curves_and_the_chosen_trial(tmp_path, capsys, synth_dir):
    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), data=synth_dir, experiments=(
        Experiment(("A", "APoc"), ("fixed", "gradnorm")),))          # 3 configurations
    out = tmp_path / "tables"
    assert tables_main(["paper", str(grid), "--out", str(out), "--example-trial", "nope"]) == 2
    assert "example trial 'nope'" in capsys.readouterr().err and not out.exists()
    assert tables_main(["paper", str(grid), "--out", str(out), "--curves",
                        "--example-trial", "Suturing_C002"]) == 0
    assert len(list((out / "figures" / "curves").glob("*.pdf"))) == 3
    said = capsys.readouterr().out.splitlines()          # off a terminal: a line per figure
    assert "multitask-tables: figure 1: per_gesture_accuracy" in said
    assert "multitask-tables: drawing the training curves of 3 configurations" in said
    assert sum(": figure " in line for line in said) == 6 + 3
    for name in ("per_gesture_accuracy", "segmentation_example", "progress_example",
                 "fold_accuracy", "gesture_vs_progress", "gradnorm_weights"):
        assert (out / "figures" / f"{name}.png").stat().st_size > 0
    figures_before = {p: p.read_bytes() for p in (out / "figures").rglob("*.png")}
    assert tables_main(["paper", str(grid), "--out", str(out), "--no-figures"]) == 0   # tables only
    assert {p: p.read_bytes() for p in (out / "figures").rglob("*.png")} == figures_before
    listed = json.loads((out / "tables.json").read_text())["files"]
    assert "figures/curves/" + next((out / "figures" / "curves").glob("*.png")).name in listed


def test_seeds_name_each_configuration_they_leave_out(tmp_path, capsys):
    from multitask.grid.spec import Experiment

    experiments = (Experiment(variants=("A", "APc"), seeds=(0, 1)),
                   Experiment(variants=("APoc",), weightings=("gradnorm",)))
    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), experiments=experiments)
    assert tables_main(["paper", str(grid), "--seeds", "1", "--no-figures", "--out",
                        str(tmp_path / "t")]) == 0
    err = capsys.readouterr().err
    assert "left out: revised/bidirectional/APoc-gradnorm, no run of seed(s) 1" in err
    assert "A-fixed, no run" not in err and "APc-fixed, no run" not in err
    assert set(pd.read_csv(tmp_path / "t" / "runs.csv").variant) == {"A", "APc"}


@pytest.mark.slow
def test_per_gesture_table_and_confusion_figure_from_saved_matrices(tmp_path, capsys):
    import json

    from multitask.evidence.render.confusion import row_normalised

    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), per_class=True, experiments=(
        Experiment(("A", "APc"), ("fixed",)), Experiment(("APoc",), ("gradnorm",))))
    out = tmp_path / "tables"
    assert tables_main(["paper", str(grid), "--out", str(out)]) == 0
    assert "per-class" not in capsys.readouterr().err
    assert (out / "figures" / "confusion.png").stat().st_size > 0
    table = pd.read_csv(out / "per_gesture.csv")
    assert list(table.columns) == ["configuration", "gesture", "folds", "precision", "recall",
                                   "f1"]
    assert set(table.configuration) == {"A-fixed", "APoc-gradnorm"}       # not APc
    assert list(table.gesture[table.configuration == "A-fixed"]) == list(GESTURES)
    rows = table.set_index(["configuration", "gesture"])
    for gesture in ABSENT:                                   # absent everywhere: NaN, not an error
        assert rows.loc[("A-fixed", gesture), "folds"] == 0
        assert np.isnan(rows.loc[("A-fixed", gesture), "recall"])
        assert rows.loc[("A-fixed", gesture), "f1"] == 0         # predicted although absent
    never = rows.loc[("A-fixed", NEVER_RECOGNISED)]
    assert never.folds == len(FOLDS) and never.recall == 0 and np.isnan(never.precision)
    # the mean over folds of each run's saved score
    saved = [json.loads((grid / f"runs/revised/bidirectional/A-fixed/seed0/{f}/metrics.json")
                        .read_text())["mean"]["gesture"]["f1_G3"] for f in FOLDS]
    assert rows.loc[("A-fixed", "G3"), "f1"] == pytest.approx(np.mean(saved), abs=1e-4)
    from multitask.evidence.runs.collect import per_class  # NaN allowed for these alone
    assert per_class("f1_G3") and per_class("precision_reach") and per_class("accuracy_G1")
    assert not any(map(per_class, ("accuracy", "f1@10", "f1@10_pooled", "accuracy_pooled")))
    shares = row_normalised(np.array([[3, 1], [0, 0]]))
    np.testing.assert_allclose(shares[0], [75, 25]) and np.isnan(shares[1]).all()


def test_an_archive_without_confusion_matrices_is_tabulated_with_one_note(grid, tmp_path,
                                                                          capsys):
    out = tmp_path / "tables"
    assert tables_main(["paper", str(grid), "--out", str(out), "--no-figures"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "per-gesture" in line]
    assert len(notes) == 1 and "predate per-class scores" in notes[0]
    assert not (out / "per_gesture.csv").exists() and (out / "summary.csv").is_file()


#: Figures meant for one column of a two-column paper; every other figure spans the page.
COLUMN_FIGURES = {"fold_accuracy", "gesture_vs_progress"}


@pytest.mark.slow
def test_every_pdf_has_truetype_fonts_and_fits_a_column_or_the_page_at_8_pt(tmp_path, synth_dir):
    """What IEEE PDF eXpress and a reader of the printed page check: no Type 3 font, a page no
    wider than the column (3.5 in) or the text (7.16 in) it is meant for, so that it prints at
    its own size, and text of 8 pt or larger (mathtext sub- and superscripts are 0.7 of it)."""
    from jigsaws_tools.plots import COLUMN_INCHES, MIN_TEXT_PT, PAGE_INCHES
    from multitask.evidence.render.confusion import write_per_class
    from multitask.evidence.studies.width import write_width
    from tests.pdf_pages import read_pdf_page

    grid = write_fake_grid(tmp_path / "grid", seeds=(0,), per_class=True, data=synth_dir,
                           experiments=(Experiment(("A", "APr", "APc", "APoc"),
                                                   ("fixed", "gradnorm")),))
    narrow = write_fake_grid(tmp_path / "h8", seeds=(0,), hidden=8, experiments=(
        Experiment(("A",)), Experiment(("APoc",), ("gradnorm",))))
    out = tmp_path / "figures"
    runs = run_rows(grid)[0]
    folds = per_fold(runs)
    figures.all_figures(grid, folds, out,
                        figures.example_truth(grid, *figures.example_trial(grid, folds)))
    write_per_class(grid, runs, folds, tmp_path, figures=True)
    curves.training_curves(narrow, out / "curves")
    write_width([grid, narrow], out)
    pdfs = sorted(out.rglob("*.pdf"))
    assert {p.stem for p in pdfs} >= {
        "per_gesture_accuracy", "segmentation_example", "progress_example", "fold_accuracy",
        "gesture_vs_progress", "gradnorm_weights", "confusion", "width", "revised-bidirectional-A"
        "-fixed", "revised-bidirectional-APoc-gradnorm"}
    for pdf in pdfs:
        page = read_pdf_page(pdf)
        assert page.font_subtypes and "Type3" not in page.font_subtypes, pdf.name
        assert page.width_in <= (COLUMN_INCHES if pdf.stem in COLUMN_FIGURES
                                 else PAGE_INCHES) + 0.005, (pdf.name, page.width_in)
        sizes = set(page.text_sizes_pt)
        full = {s for s in sizes if s >= MIN_TEXT_PT}
        scripts = sizes - full
        assert full and all(any(abs(s - 0.7 * f) < 0.05 for f in full) for s in scripts), (
            pdf.name, sorted(sizes))


def test_no_committed_figure_holds_a_type3_font():
    """Every PDF under results/ embeds its fonts as TrueType (what IEEE PDF eXpress checks): a
    figure drawn before the style set ``pdf.fonttype`` must be redrawn, from its archive."""
    from pathlib import Path

    from tests.pdf_pages import read_pdf_page

    results = Path(__file__).resolve().parents[1] / "results"
    pdfs = sorted(results.rglob("*.pdf"))
    assert pdfs
    assert [p.relative_to(results).as_posix() for p in pdfs
            if "Type3" in read_pdf_page(p).font_subtypes] == []
