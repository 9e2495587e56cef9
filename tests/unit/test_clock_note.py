"""A radar clock offset the fit carries is said in words when the data determine it
(bayesdrag.pipeline.model_check.clock_note): a track whose t = 0 is the first radar sample, 0.5 s after
the launch, used to be told by the launch check; with the offset fitted by default it is told here."""
import pytest

from bayesdrag.pipeline.model_check import CLOCK_NOTE_SD, clock_note


def _ml(dt, sd=None, crb=None):
    ml = {"params": {"radar_time.dt": dt}, "crb": {"radar_time.dt": crb}}
    if sd is not None:
        ml["with_effects"] = {"sizes": {"radar_time.dt": {"value": dt, "sd": sd}}}
    return ml


def test_a_determined_late_origin_is_said_with_the_numbers_the_json_holds():
    (warning,) = clock_note(_ml(0.5001, sd=0.0012, crb=0.0011))
    assert warning.kind == "clock" and warning.params == ("radar_time.dt",)
    note = str(warning)
    assert note.startswith("radar_time.dt = 0.5001 +- 0.0012 s") and "0.5 s after the launch" in note
    assert "shift t so that t = 0 is the launch" in note


def test_an_early_clock_is_said_so():
    (warning,) = clock_note(_ml(-0.06, crb=0.002))       # no sizes: the bound is the sd
    note = str(warning)
    assert "0.06 s before the launch" in note and "that early" in note


@pytest.mark.parametrize("ml", [_ml(0.003, sd=0.002), {"params": {"drag.c0": 0.3}}, {}],
                         ids=["within-noise", "no-clock", "empty"])
def test_nothing_is_said_without_a_determined_offset(ml):
    assert clock_note(ml) == []
    assert CLOCK_NOTE_SD == 3.0
