"""The runner end to end on tiny inputs: results.json keys, the long table, one self-contained report.html; CLI."""

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from evedge.bench.cli import bench
from evedge.bench.exp_ransac import RansacStudyParams
from evedge.bench.paper import run_paper
from evedge.bench.report import write_report

TINY_SCENE = Path(__file__).resolve().parents[1] / "data" / "tiny_shapes.toml"


@pytest.fixture(scope="module")
def tiny_run(moving_edge, tmp_path_factory):
    from evedge.io import write_ecd

    tmp = tmp_path_factory.mktemp("paper")
    folder = write_ecd(tmp / "rec", moving_edge)
    out = tmp / "out"
    res = run_paper(out, quick=True, progress=False,
                    ransac_params=RansacStudyParams(repetitions=5, noise_levels_px=(0.0, 0.5)),
                    similarity_recording=moving_edge, lifetime_recordings={"stripes_sim": moving_edge},
                    real_path=folder)
    return out, res


def test_results_json_has_the_keys(tiny_run):
    out, res = tiny_run
    assert res["errors"] == {}
    data = json.loads((out / "results.json").read_text())
    for key in ("fmeasure", "lifetime", "cdm", "real", "verdicts", "params", "run"):
        assert key in data, key
    assert set(data["fmeasure"]) == {"global", "scattered"}
    assert "intra_delta_0.25" in data["fmeasure"]["global"]
    for m in ("proposed", "mueggler"):
        lt = data["lifetime"]["stripes_sim"][m]
        assert "median_rel_error" in lt and 0 < lt["share_estimated"] <= 1
        assert "shoulder_peaks" in lt
    scene = next(iter(data["cdm"]))
    assert set(data["cdm"][scene]["exact"]["proposed"]) >= {"slow", "fast"}
    rec = next(iter(data["real"]))
    assert "cdm_per_frame" in data["real"][rec]["proposed"]
    statuses = {v["status"] for v in data["verdicts"]}
    assert statuses <= {"holds", "fails", "not checked"}
    assert any(v["claim"].startswith("Under global noise") for v in data["verdicts"])
    assert data["run"]["versions"]["numpy"]


def test_results_name_figures_relative_to_the_output_folder(tiny_run):
    # the CLI builds the run in a temporary folder and swaps it in: no stored path may point there
    out, _ = tiny_run
    data = json.loads((out / "results.json").read_text())
    figures = [f for v in data["figures"].values() for f in v]
    assert len(figures) >= 8
    assert all(not Path(f).is_absolute() and (out / f).is_file() for f in figures)
    assert str(out) not in (out / "results.json").read_text()
    for name in ("ransac/ransac_study.json", "lifetime/lifetime.json"):
        assert all((out / name).parent.joinpath(f).is_file() for f in json.loads((out / name).read_text())["figures"])


def test_both_display_policies_in_results_and_report(tiny_run):
    out, res = tiny_run
    data = json.loads((out / "results.json").read_text())
    disp = data["display"]
    assert disp["primary"] == "predecessor" and data["params"]["display"]["primary"] == "predecessor"
    assert disp["policies"]["lifetime_only"]["methods"] == {"proposed": "proposed_noclear",
                                                           "mueggler": "mueggler_noclear"}
    scene = next(iter(data["cdm"]))
    rec = next(iter(data["real"]))
    for key in ("proposed", "mueggler", "proposed_noclear", "mueggler_noclear", "acc_1ms"):
        assert key in data["cdm"][scene]["exact"], key
        assert key in data["real"][rec], key
    by_display = {}
    for v in data["verdicts"]:
        by_display.setdefault(v["display"], []).append(v)
    # the CDM claims (3 per truth kind) and the real-frames claim, once per policy
    n_truth = len(data["cdm"][scene])
    for d in ("predecessor", "lifetime_only"):
        vs = by_display[d]
        assert sum("beats Mueggler" in v["claim"] for v in vs) == n_truth
        assert sum("real frames" in v["claim"] for v in vs) >= 1
        assert all(v["status"] in ("holds", "fails") for v in vs)
    # non-CDM claims carry no display
    assert any(v["claim"].startswith("Under global noise") and v["display"] is None for v in data["verdicts"])
    summ = disp["summary"]
    assert summ["policies"]["predecessor"]["n"] == len(by_display["predecessor"])
    assert any("display policy" in n.lower() and "primary" in n.lower() for n in data["notes"])
    text = (out / "report.html").read_text()
    assert "Display policy: the primary comparison uses the predecessor display" in text
    assert "For comparison, under the lifetime-only display" in text
    assert "primary display policy" in text  # panel and real-frames captions


def test_report_is_one_self_contained_page(tiny_run):
    out, res = tiny_run
    text = (out / "report.html").read_text()
    assert text.startswith("<!doctype html>")
    assert "Do the paper's claims hold?" in text
    # every figure is inlined; no reference to files beside the page
    n_figs = sum(len(v) for v in res["figures"].values())
    assert text.count("data:image/png;base64,") == n_figs >= 8
    assert not re.search(r"src=['\"](?!data:)", text)


def test_missing_data_is_skipped_and_a_failure_reported(tmp_path, monkeypatch):
    res = run_paper(tmp_path / "a", quick=True, progress=False, experiments=("real",),
                    real_path=tmp_path / "does_not_exist")
    assert "real" in res["skipped"] and not res["errors"]
    assert "Skipped" in (tmp_path / "a" / "report.html").read_text()

    import evedge.bench.exp_real as exp_real

    def boom(*args, **kwargs):
        raise RuntimeError("simulated failure")

    monkeypatch.setattr(exp_real, "run_real", boom)
    res = run_paper(tmp_path / "b", quick=True, progress=False, experiments=("real",))
    assert "real" in res["errors"] and "simulated failure" in res["errors"]["real"]
    assert "failed" in (tmp_path / "b" / "report.html").read_text()

    # a simulated experiment has no recording to miss: a FileNotFoundError there (a missing scene
    # file, say) is a failure, not a skip that would leave its verdicts quietly 'not checked'
    import evedge.bench.exp_ransac as exp_ransac

    def missing(*args, **kwargs):
        raise FileNotFoundError("scenes/x.toml")

    monkeypatch.setattr(exp_ransac, "run_ransac_study", missing)
    res = run_paper(tmp_path / "c", quick=True, progress=False, experiments=("ransac",))
    assert "ransac" in res["errors"] and "ransac" not in res["skipped"]


def test_write_report_minimal(tmp_path):
    path = write_report(tmp_path / "r.html", {"verdicts": [], "run": {}}, figures={}, notes=["a note"])
    assert "a note" in path.read_text()


def test_cli_lists_the_experiments_and_demo_help():
    from evedge.bench.cli import demo

    runner = CliRunner()
    r = runner.invoke(bench, ["--help"])
    assert r.exit_code == 0
    for name in ("paper", "ransac", "lifetime", "similarity", "qualitative", "real"):
        assert name in r.output
    r = runner.invoke(demo, ["--help"])
    assert r.exit_code == 0 and "demo_out" in r.output


def test_cli_ransac_and_unknown_experiment(tmp_path):
    runner = CliRunner()
    r = runner.invoke(bench, ["ransac", "-o", str(tmp_path), "--repetitions", "3", "--no-progress"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "ransac_study.json").exists()
    with pytest.raises(ValueError, match="unknown experiments"):
        run_paper(tmp_path, experiments=("nope",))


def test_cli_real_with_one_display_policy(moving_edge, tmp_path):
    from evedge.io import write_ecd

    folder = write_ecd(tmp_path / "rec", moving_edge)
    r = CliRunner().invoke(bench, ["real", "-o", str(tmp_path / "out"), "--path", str(folder), "--quick",
                                   "--no-progress", "--display", "lifetime_only"])
    assert r.exit_code == 0, r.output
    data = json.loads(next((tmp_path / "out").glob("real_*.json")).read_text())
    res = next(iter(data["recordings"].values()))
    assert set(res["displays"]["policies"]) == {"lifetime_only"}
    methods = set(next(iter(res["cdm"].values())))
    assert {"proposed_noclear", "mueggler_noclear", "acc_1ms"} <= methods
    assert not methods & {"proposed", "mueggler"}
    r = CliRunner().invoke(bench, ["real", "-o", str(tmp_path / "o2"), "--display", "nope"])
    assert r.exit_code != 0 and "nope" in r.output


def test_cli_unusable_output_directory_is_a_usage_error(tmp_path):
    """-o into a file, or below a file: a clear error before any experiment runs, no traceback."""
    from evedge.bench.cli import demo

    a_file = tmp_path / "taken"
    a_file.write_text("x")
    for cmd, args in ((bench, ["similarity", "-o", str(a_file / "sub"), "--quick", "--no-progress"]),
                      (bench, ["ransac", "-o", str(a_file), "--quick", "--no-progress"]),
                      (demo, ["-o", str(a_file / "sub"), "--no-progress"])):
        r = CliRunner().invoke(cmd, args)
        assert r.exit_code == 2, (args, r.output)
        assert isinstance(r.exception, SystemExit), (args, r.exception)
        assert "--out" in r.output, r.output
    assert a_file.read_text() == "x"


def test_cli_bad_bench_options_are_usage_errors(tmp_path):
    """Negative seed, zero repetitions, unknown scene, unreadable --path: 'Error: ...' without traceback."""
    junk = tmp_path / "junk.txt"
    junk.write_text("not events\n")
    out = str(tmp_path / "o")
    cases = [(["ransac", "-o", out, "--repetitions", "0"], "--repetitions", 2),
             (["ransac", "-o", out, "--seed", "-1"], "--seed", 2),
             (["similarity", "-o", out, "--scene", "nope"], "shapes_translation", 2),
             (["real", "-o", out, "--path", str(junk), "--quick"], "junk.txt", 1)]
    for args, needle, code in cases:
        r = CliRunner().invoke(bench, args + ["--no-progress"])
        assert r.exit_code == code, (args, r.output, r.exception)
        assert isinstance(r.exception, SystemExit), (args, r.exception)
        assert "Error:" in r.output and needle in r.output, (args, r.output)


def test_report_states_the_policy_effect_from_the_numbers():
    """Regression: the report asserted, by hand, that the display policy moves the CDM more than the
    estimator does (false on slider_depth: about 1 point vs about 40). It now reports both, computed
    from the table (verdicts.policy_effect); the report only renders them."""
    from evedge.bench.report import _display_headline, _policy_effect_text
    from evedge.bench.results import ResultsTable, cdm_rows, real_rows
    from evedge.bench.verdicts import all_verdicts, display_summary, policy_effect

    def sec(m):
        return {"slow": {"median": m, "n": 3}, "fast": {"median": m, "n": 3}}

    cdm = {"exact": {"proposed": sec(80.0), "proposed_noclear": sec(70.0), "mueggler": sec(50.0),
                     "mueggler_noclear": sec(46.0), "acc_1ms": sec(10.0), "acc_30ms": sec(20.0)}}
    real = {"proposed": {"median": {"c": 40.0}}, "proposed_noclear": {"median": {"c": 41.0}},
            "mueggler": {"median": {"c": None}}, "mueggler_noclear": {"median": {"c": 5.0}}}
    table = ResultsTable(cdm_rows("similarity", "s", cdm))
    table.extend(real_rows("r", real), experiment="real")
    results = {"policy_effect": policy_effect(table), "run": {}}
    text = _policy_effect_text(results["policy_effect"])
    # policy: |80-70|, |50-46| twice (slow, fast), |40-41|: max 10, median 4;
    # estimator: |80-50|, |70-46| twice, |41-5| (Mueggler's null median is left out): max 36, median 30
    assert "by up to 10.0 points, median 4.0" in text
    assert "by up to 36.0, median 30.0" in text
    results["display"] = {"summary": display_summary(all_verdicts(table))}
    html_text = _display_headline(results)  # the report's display-policy paragraph
    assert "moves the CDM more than the estimator" not in html_text
    assert "by up to 36.0" in html_text
    assert _policy_effect_text(None) == "" and policy_effect(ResultsTable()) is None
    from evedge.bench.paper import NOTES

    assert not any("more than the estimator" in n for n in NOTES)


def _legacy_counts(verdicts, text):
    """(holds, fails) of the detailed verdicts whose claim (after its [context]) starts like ``text``."""
    vs = [v for v in verdicts if v["claim"].split("] ", 1)[-1].startswith(text[:40])]
    return sum(v["status"] == "holds" for v in vs), sum(v["status"] == "fails" for v in vs)


def test_results_table_and_declarative_claims_agree_with_the_verdicts(tiny_run):
    """The long table holds the experiments' numbers, and the claims computed from it (declarative
    rules) agree with the detailed verdicts (computed from the same table), group for group."""
    from markupsafe import escape

    from evedge.bench.claims import CLAIMS, evaluate
    from evedge.bench.results import read_results

    out, res = tiny_run
    table = read_results(out / "results.h5")
    assert read_results(out / "results.csv").rows == table.rows
    assert set(table.unique("experiment")) == {"ransac", "lifetime", "similarity", "real"}
    scene = next(iter(res["cdm"]))
    # a number of the nested results is the same number in the table
    want = res["cdm"][scene]["exact"]["proposed_noclear"]["fast"]["median"]
    assert table.value(experiment="similarity", reference="exact", variant="proposed_noclear", section="fast",
                       metric="cdm_median") == want
    assert table.unique("method", experiment="similarity", variant="proposed_noclear") == ["intra"]
    assert table.unique("display", experiment="similarity", variant="proposed_noclear") == ["lifetime_only"]
    claims = {c["name"]: c for c in evaluate(table)}
    assert claims == {c["name"]: c for c in res["claims"]}
    checked = 0
    for claim in CLAIMS:
        c = claims[claim.name]
        assert (c["n_holds"], c["n_fails"]) == _legacy_counts(res["verdicts"], claim.text), claim.name
        checked += c["n_checks"]
    assert checked >= 10
    html = (out / "report.html").read_text()
    board = html[html.index("<h2>Leaderboard"):html.index("<h2>Do the paper")]
    assert "<b>" in board and "proposed (intra-pixel-area)" in board and "vs exact" in board
    for c in claims.values():
        assert str(escape(c["claim"])) in html


def test_cli_prints_one_line_per_claim(tmp_path):
    res = CliRunner().invoke(bench, ["paper", "-o", str(tmp_path / "o"), "--quick", "--only", "similarity",
                                     "--scene", str(TINY_SCENE), "--no-progress"])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("  [")]
    from evedge.bench.claims import CLAIMS

    assert len(lines) == len(CLAIMS)
    assert any("checks hold)" in ln for ln in lines)


def test_verdicts_from_the_table_equal_those_from_the_nested_results(tiny_run):
    """all_verdicts reads only the table (CSV or HDF5); its views rebuild exactly the nested results the
    checks were written for (same verdicts, evidence and details)."""
    from evedge.bench.results import cdm_view, diagnostics_view, lifetime_view, read_results, real_view
    from evedge.bench.verdicts import (all_verdicts, cdm_verdicts, intra_verdicts, lifetime_verdicts,
                                       real_verdicts)

    out, res = tiny_run
    table = read_results(out / "results.csv")
    data = json.loads((out / "results.json").read_text())
    from_nested = (cdm_verdicts(res["cdm"], res["cdm_diagnostics"])
                   + intra_verdicts(res["fmeasure"], res["truth_tolerance_sensitivity"])
                   + lifetime_verdicts(res["lifetime"], res["lifetime_datasets"]) + real_verdicts(res["real"]))
    assert all_verdicts(table) == all_verdicts(read_results(out / "results.h5")) == res["verdicts"] == from_nested
    assert cdm_view(table).keys() == res["cdm"].keys()
    assert diagnostics_view(table) == res["cdm_diagnostics"]
    lifetime, _ = lifetime_view(table)
    for m in ("proposed", "mueggler"):
        assert lifetime["stripes_sim"][m]["peaks"] == res["lifetime"]["stripes_sim"][m]["peaks"]
        assert lifetime["stripes_sim"][m]["shoulder_peaks"] == res["lifetime"]["stripes_sim"][m]["shoulder_peaks"]
    assert {k: {m: v["median"] for m, v in per.items()} for k, per in real_view(table).items()} == \
        {k: {m: v["median"] for m, v in per.items()} for k, per in data["real"].items()}
