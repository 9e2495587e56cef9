"""A firing table of another shell whose level the selection explains alone: the demo's 6-DOF
155 mm track (M101 drag, a spin's lift) with the G1 function as the round's table. The level
(``density``, 0.54) leaves far more than the noise, and the table's shape is significant beside
it although it leaves a third effect (the lift) part of what is left: the round is judged as
beside a table of another shell (``diagnosis.selection.shape_beside_level``), the drag effects in
their joint fit and the lift found against a fitted Cd."""
from pathlib import Path

import pytest

import bayesdrag
from bayesdrag.diagnosis import diagnose


@pytest.fixture(scope="module")
def demo_with_g1(tmp_path_factory):
    from bayesdrag.commands.demo import demo_inputs

    tp, rp = demo_inputs()
    text = Path(rp).read_text().replace('reference_drag = "cd_m101.csv"', 'reference_drag = "G1"')
    assert 'reference_drag = "G1"' in text
    folder = tmp_path_factory.mktemp("g1")
    (folder / "round.toml").write_text(text)
    return bayesdrag.read_track(tp), bayesdrag.read_round(folder / "round.toml")


def test_the_shape_beside_the_level_is_a_table_of_another_shell(demo_with_g1):
    track, rnd = demo_with_g1
    rec = diagnose(track, rnd).record
    assert set(rec["verdict"]) == {"density", "drag_shape", "lift"}, rec["verdict"]
    assert any("another shell's shape" in n for n in rec["notes"]), rec["notes"]
    lift = next(r for r in rec["effects"] if r["name"] == "lift")
    assert lift.get("judged_against") == "fitted Cd", lift


@pytest.mark.parametrize("case_id", ["pm-density-10", "pm-density-11"])
def test_a_density_error_beside_the_right_table_stays_the_level_alone(case_id):
    """The shape's rule must not turn a real density change into a table of another shell: the
    round's table is the shell's own (M101), the air 5 % denser (6 % thinner), and the shape adds
    nothing significant beside the level (the diagnosis suite's cases)."""
    from acceptance import cases as C

    case = next(c for c in C.EFFECT_CASES if c.id == case_id)
    rec = diagnose(C.make_track(case), C.diagnosis_round(case)).record
    assert rec["verdict"] == ["density"], rec["verdict"]
    assert not any("another shell's shape" in n for n in rec["notes"]), rec["notes"]
