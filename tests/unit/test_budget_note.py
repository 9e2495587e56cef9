"""The report's budget note names each kind of source for what it is: declared (with a prior),
an effect fitted beside Cd (no prior), or assumed by the fit (the launch yaw of a spinning shell)."""
from bayesdrag.report.fit import budget_context


def _summary(by_source, assumed=None, fitted=()):
    n = 3
    b = {"mach": [1.0, 1.5, 2.0], "total_sd": [0.002] * n, "conditional_on": ["mass"],
         "by_source": {k: [0.001] * n for k in by_source}}
    if assumed:
        b["assumed"] = assumed
    return {"uncertainty_budget": b, "cd": [{"mach": m, "ml": 0.3} for m in b["mach"]],
            "ml": {"mach_range_determined": [1.0, 2.0], "with_effects": {"fitted": list(fitted)}}}


def test_effects_declared_and_assumed_sources_are_told_apart():
    s = _summary(["statistical", "density", "lift", "launch_yaw", "cross"],
                 assumed={"launch_yaw": {"sd_deg": 3.0, "decay_per_s": 0.5, "why": "a spinning shell"}},
                 fitted=["lift"])
    note = budget_context(s)["note"]
    assert "declared sources density (fitted with their priors)" in note
    assert "effects lift (fitted beside Cd" in note
    assert "assumed launch_yaw (sd 3 deg: a spinning shell)" in note
    assert "declared sources density, lift" not in note and "declared sources launch_yaw" not in note


def test_without_declared_sources_the_note_says_so_and_still_names_the_effect():
    note = budget_context(_summary(["statistical", "lift", "cross"], fitted=["lift"]))["note"]
    assert note.startswith("No systematic source is declared: includes the effects lift")
