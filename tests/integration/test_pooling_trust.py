"""The pooling trusts no file of a round's folder (issue 44, item 11).

The review: a ``pooling.json`` with Cd = 1e300 at every node pooled to a campaign Cd of 9.7e151
with ``success: true``; both rounds' ``result.json`` and ``pooling.json`` edited by +5 % were
skipped on a rerun (the done marker's fingerprint covered only inputs and options) and moved the
campaign Cd by +5.0 %. Now ``pooling.json`` is bounded (Cd in (0, 5], a covariance of sane
size), must name its round, be the file the round's fit wrote (the SHA-256 of it and of
``result.json`` are in ``done.fit.json``) and agree with ``result.json``'s Cd rows; a round
failing any of it is left out of the pooling with one line naming the round and the file.

One small campaign (two simulated rounds, one drag factor, no sampling) is fitted once; each
test edits a copy of its output folder and reruns ``bayesdrag fit CAMPAIGN``, which skips the
finished rounds and only pools.
"""
import copy
import hashlib
import json
import re
import shutil

import numpy as np
import pytest

from bayesdrag.campaign.synthetic import simulate_campaign
from bayesdrag.cli import main

#: fit options of the campaign: one drag factor, no sampling (a few seconds a round)
QUICK = ["--no-mcmc", "--drag", "reference-scale", "--quiet"]
ROUNDS = ("r1", "r2")


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """The campaign file, its fitted output folder and the campaign.json of that first run."""
    d = tmp_path_factory.mktemp("pooling")
    path, _ = simulate_campaign(d, n_rounds=2, scatter=0.01, rng=np.random.default_rng(4), dt=0.2)
    out = d / "out"
    assert main(["fit", str(path), "-o", str(out), *QUICK]) == 0
    return path, out, json.loads((out / "campaign.json").read_text())


@pytest.fixture
def out(fitted, tmp_path):
    """A copy of the fitted output folder to edit."""
    dst = tmp_path / "out"
    shutil.copytree(fitted[1], dst)
    return dst


def _rerun(fitted, out, capsys):
    """Rerun the campaign into ``out``: (exit status, stderr lines, stdout)."""
    capsys.readouterr()
    code = main(["fit", str(fitted[0]), "-o", str(out), *QUICK[:-1]])     # the summary on stdout
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err
    return code, cap.err.strip().splitlines(), cap.out


def _edit(path, change):
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc, indent=2))


def _scale_pooling(doc, f=1.05):
    doc["cd"] = [v * f for v in doc["cd"]]
    doc["cd_crb_sd"] = [v * f for v in doc["cd_crb_sd"]]
    doc["cov"] = [[v * f * f for v in row] for row in doc["cov"]]


def _scale_result(doc, f=1.05):
    for r in doc["cd"]:
        for k in ("ml", "crb_sd", "crb_sd_colored", "crb_sd_statistical", "band_sd"):
            if r.get(k) is not None:
                r[k] *= f


def _left_out(lines, name, pattern):
    """The one stderr line about round ``name``: left out of the pooling, matching ``pattern``."""
    mine = [ln for ln in lines if f"round {name} " in ln]
    assert len(mine) == 1, lines
    assert re.search(rf"^bayesdrag: round {name} \(pool\) failed: left out of the pooling: {pattern}", mine[0]), mine[0]


def _campaign(out):
    p = out / "campaign.json"
    return json.loads(p.read_text()) if p.is_file() else None


# ------------------------------------------------------------------------------------------------
# the review's two reproducers
def test_a_pooling_input_of_cd_1e300_leaves_its_round_out(fitted, out, capsys):
    """Cd = 1e300 at every node of r2: refused by the bound (before the marker's hash), r2 left
    out with its reason, the campaign pooled from r1 alone."""
    _edit(out / "r2" / "pooling.json", lambda d: d.update(cd=[1e300] * len(d["cd"])))
    code, lines, _ = _rerun(fitted, out, capsys)
    assert code == 1, lines
    _left_out(lines, "r2", r".*r2/pooling\.json: not a pooling input of this version \(cd is 1e\+300 at Mach "
                           r"\d\.\d\d, outside the physical range \(0, 5\] of a drag coefficient\); delete "
                           r".*r2/done\.fit\.json to refit the round")
    camp = _campaign(out)
    assert camp["rounds"] == ["r1"] and [f["name"] for f in camp["failed"]] == ["r2"]
    assert max(r["mean"] for r in camp["cd"]) < 1.0


@pytest.mark.parametrize("edited", [("result.json", "pooling.json"), ("pooling.json",)])
def test_rounds_edited_by_5_percent_are_not_pooled_from_the_edited_files(fitted, out, capsys, edited):
    """Both rounds' files edited by +5 % (Cd and its sds, consistently): the rerun skips the
    rounds (same inputs) but pools neither; each is named with the file that changed."""
    for n in ROUNDS:
        if "result.json" in edited:
            _edit(out / n / "result.json", _scale_result)
        _edit(out / n / "pooling.json", _scale_pooling)
    code, lines, stdout = _rerun(fitted, out, capsys)
    assert code == 1, lines
    assert "0 jobs run, 2 skipped" in stdout
    first = edited[0].replace(".", r"\.")
    for n in ROUNDS:
        _left_out(lines, n, rf".*{n}/{first}: not the file the round's fit wrote \(its SHA-256 differs from the one "
                            rf"done\.fit\.json records\): the round's folder was edited after the fit; delete "
                            rf".*{n}/done\.fit\.json to refit the round")
    assert "campaign: no fitted round to pool" in stdout
    camp = _campaign(out)          # the first run's campaign stays, or none: never the edited Cd
    assert camp is None or camp["cd"] == fitted[2]["cd"]


def test_deleting_the_markers_of_edited_rounds_refits_them(fitted, out, capsys):
    """The fix the refusal names: without its marker the round is redone, and the campaign is the
    first run's again (the pooling is seeded, the fit deterministic)."""
    for n in ROUNDS:
        _edit(out / n / "result.json", _scale_result)
        _edit(out / n / "pooling.json", _scale_pooling)
        (out / n / "done.fit.json").unlink()
    code, lines, stdout = _rerun(fitted, out, capsys)
    assert code == 0, lines
    assert "2 jobs run, 0 skipped" in stdout
    np.testing.assert_allclose([r["mean"] for r in _campaign(out)["cd"]], [r["mean"] for r in fitted[2]["cd"]],
                               rtol=1e-9)


# ------------------------------------------------------------------------------------------------
# what else the pooling checks
def test_a_rewritten_marker_does_not_hide_an_edited_pooling_input(fitted, out, capsys):
    """pooling.json +5 % and its hash rewritten in done.fit.json: result.json's Cd rows disagree."""
    p = out / "r2" / "pooling.json"
    _edit(p, _scale_pooling)
    digest = hashlib.sha256(p.read_bytes()).hexdigest()
    _edit(out / "r2" / "done.fit.json", lambda d: d.setdefault("outputs", {}).update({"pooling.json": digest}))
    code, lines, _ = _rerun(fitted, out, capsys)
    assert code == 1, lines
    _left_out(lines, "r2", r".*r2/pooling\.json: disagrees with .*r2/result\.json \(Cd at Mach \d\.\d\d is [\d.]+ in "
                           r"pooling\.json, result\.json's rows allow [\d.]+ to [\d.]+ there\); delete .*done\.fit\.json")
    assert _campaign(out)["rounds"] == ["r1"]


def test_a_pooling_input_copied_from_another_round_is_refused(fitted, out, capsys):
    """r1's pooling.json (and result.json) copied into r2's folder would pool r1 twice."""
    for f in ("pooling.json", "result.json"):
        shutil.copy(out / "r1" / f, out / "r2" / f)
    code, lines, _ = _rerun(fitted, out, capsys)
    assert code == 1, lines
    _left_out(lines, "r2", r".*r2/pooling\.json: the pooling input of round 'r1', not of round 'r2'")
    assert _campaign(out)["rounds"] == ["r1"]


def test_a_marker_without_output_hashes_is_redone(fitted, out, capsys):
    """A marker of an earlier version (no ``outputs``): the round is fitted again, not pooled
    unchecked; its new marker holds the hashes."""
    _edit(out / "r2" / "done.fit.json", lambda d: d.pop("outputs", None))
    code, lines, stdout = _rerun(fitted, out, capsys)
    assert code == 0, lines
    assert "1 jobs run, 1 skipped" in stdout
    assert _campaign(out)["rounds"] == list(ROUNDS)
    assert set(json.loads((out / "r2" / "done.fit.json").read_text())["outputs"]) == {"result.json", "pooling.json"}


def test_an_untouched_rerun_skips_and_pools_as_before(fitted, out, capsys):
    for n in ROUNDS:
        marker = json.loads((out / n / "done.fit.json").read_text())
        assert marker["outputs"] == {f: hashlib.sha256((out / n / f).read_bytes()).hexdigest()
                                     for f in ("result.json", "pooling.json")}
    code, lines, stdout = _rerun(fitted, out, capsys)
    assert code == 0, lines
    assert "0 jobs run, 2 skipped" in stdout
    assert _campaign(out)["cd"] == fitted[2]["cd"] and _campaign(out)["success"] is True


# ------------------------------------------------------------------------------------------------
# the bounds of a pooling input and the cross-check, without a campaign run
@pytest.fixture(scope="module")
def pin(fitted):
    """r1's pooling.json and result.json."""
    out = fitted[1]
    return json.loads((out / "r1" / "pooling.json").read_text()), json.loads((out / "r1" / "result.json").read_text())


def _cov_times(f):
    return lambda d: d.update(cov=(np.asarray(d["cov"]) * f).tolist())


def _not_psd(d):
    """Nodes 0 and 1 correlated by 1.05: an eigenvalue of -5 % of their variance, small enough
    for the relative floor to hide it."""
    cov = np.asarray(d["cov"])
    v = float(np.sqrt(cov[0, 0] * cov[1, 1]))
    cov[0, 1] = cov[1, 0] = 1.05 * v
    d["cov"] = cov.tolist()


@pytest.mark.parametrize("craft, message", [
    (lambda d: d.update(cd=[1e300] * len(d["cd"])), r"cd is 1e\+300 at Mach .*outside the physical range \(0, 5\]"),
    (lambda d: d["cd"].__setitem__(3, 5.5), r"cd is 5\.5 at Mach .*outside the physical range \(0, 5\]"),
    (lambda d: d.update(cov=np.diag(np.full(len(d["cd"]), 30.0)).tolist()), r"cov has a variance outside \[0, 5\^2\]"),
    (_cov_times(1e200), r"cov has a variance outside"),
    (lambda d: d["cov"][0].__setitem__(1, d["cov"][0][1] + 1e-3), r"cov is not a finite symmetric matrix"),
    (lambda d: d["cov"][0].__setitem__(0, float("nan")), r"cov is not a finite symmetric matrix"),
    (_not_psd, r"cov is not a covariance \(not positive semi-definite\)"),
    (lambda d: d["cd_crb_sd"].__setitem__(0, -1e-3), r"cd_crb_sd is not a value in \[0, 5\]"),
    (lambda d: d.update(reference=[1e300] * len(d["cd"])), r"reference is not a value in \(0, 5\]"),
    (lambda d: d.update(name="r" * 65), r"name or drag_model is longer than 64 characters"),
    (lambda d: d.pop("cd_crb_sd"), r"missing or not numbers"),
])
def test_check_input_bounds_a_pooling_input(pin, craft, message):
    from bayesdrag.campaign.pooling import check_input

    doc = copy.deepcopy(pin[0])
    check_input(doc)
    craft(doc)
    with pytest.raises(ValueError, match=message):
        check_input(doc)


@pytest.mark.parametrize("craft, message", [
    (lambda d, r: _scale_pooling(d, 1.05), r"Cd at Mach .* is .* in pooling\.json, result\.json's rows allow"),
    (lambda d, r: _scale_pooling(d, 1.01), r"Cd at Mach .* in pooling\.json"),
    (lambda d, r: d.update(cov=(np.asarray(d["cov"]) / 4).tolist()), r"sd of Cd \(its cov against the rows' "
                                                                       r"crb_sd_colored\) at Mach"),
    (lambda d, r: d.update(drag_model="spline"), r"drag model 'spline' in pooling\.json, 'reference-scale' in "
                                                 r"result\.json"),
    (lambda d, r: r["ml"].update(mach_range_data=[0.5, 2.0]), r"Mach range .* in pooling\.json"),
    (lambda d, r: r.update(scheme=2), r"not a Scheme 1 result"),
    (lambda d, r: r["cd"].reverse(), r"not a finite table of increasing Mach"),
])
def test_a_pooling_input_must_agree_with_its_result(pin, craft, message):
    from bayesdrag.campaign.pooling import check_against_result

    doc, res = copy.deepcopy(pin[0]), copy.deepcopy(pin[1])
    check_against_result(doc, res)
    craft(doc, res)
    with pytest.raises(ValueError, match=message):
        check_against_result(doc, res)


def test_the_cross_check_takes_a_curve_with_a_jump(fitted):
    """poly2-split's Cd jumps at its split Mach: no interpolation between the rows follows it,
    the range of the two rows around a node does; a 1 % change of one node is still refused."""
    from bayesdrag.campaign.pooling import check_against_result, mach_nodes
    from bayesdrag.estimate.cd.table import cd_grid

    def cd(m):
        m = np.asarray(m, float)
        return np.where(m < 1.0, 0.16 + 0.05 * (m - 0.8) ** 2, 0.40 - 0.08 * (m - 1.0) + 0.01 * (m - 1.0) ** 2)

    def sd(m):
        return 1e-3 * (1.0 + 0.2 * np.asarray(m, float))

    lo, hi = 0.8123, 2.3456
    grid, nodes = cd_grid(lo, hi), mach_nodes(lo, hi)
    assert 1.0 in np.round(nodes, 6)
    rows = [{"mach": float(m), "ml": float(cd(m)), "crb_sd": float(sd(m)), "crb_sd_colored": float(sd(m))}
            for m in grid]
    res = {"scheme": 1, "drag_model": "poly2-split", "ml": {"mach_range_data": [lo, hi]}, "cd": rows}
    doc = {"mach": nodes.tolist(), "cd": cd(nodes).tolist(), "cd_crb_sd": sd(nodes).tolist(),
           "cov": np.diag(sd(nodes) ** 2).tolist(), "mach_range": [lo, hi], "covariance": "colored",
           "drag_model": "poly2-split", "name": "x"}
    check_against_result(doc, res)
    i = int(np.argmin(np.abs(nodes - 1.5)))
    doc["cd"][i] *= 1.01
    with pytest.raises(ValueError, match=r"Cd at Mach 1\.50 is"):
        check_against_result(doc, res)
