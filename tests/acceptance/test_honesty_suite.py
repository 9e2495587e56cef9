"""The honesty suite (:mod:`acceptance.honesty_suite`): flights with an effect the round does not
declare, and with none, judged on the rows the default fit claims. A row marked ``determined``
whose Cd is wrong (more than 2 % from the truth and more than 3 of its ``band_sd``) is the worst
defect; the fast subset holds the flights that produced such rows before the model-error term
(issue 27), the slow run every case."""
import pytest

from acceptance import honesty_suite as hs

#: flights that claimed wrong rows before the model-error term: AR(1) noise with outliers and no
#: effect at all; a 3 m/s head-cross wind on AR(1) noise; a flat 8 m/s headwind the residuals hide
FAST_CASES = ("w-pm-null-102", "w-pm-wind-04", "w-pm-wind-01")
#: a white-noise flight with no effect: nothing to widen, its determined span must stay whole
CLEAN_CASE = "w-pm-null-100"
#: share of a clean flight's judged span that must stay determined
CLEAN_DETERMINED = 0.95


@pytest.mark.parametrize("cid", FAST_CASES)
def test_no_wrong_determined_row(cid):
    r = hs.run_case(hs.case_by_id(cid))
    assert "error" not in r, r.get("error")
    assert r["determined_wrong"] == 0, (f"{cid}: {r['determined_wrong']} of {r['determined']} determined rows wrong "
                                        f"(worst {r['worst_z_wrong']:.1f} band sd)")


def test_clean_flight_keeps_its_span():
    r = hs.run_case(hs.case_by_id(CLEAN_CASE))
    assert r["determined_wrong"] == 0
    assert r["determined_fraction"] >= CLEAN_DETERMINED, r["determined_fraction"]
    assert r["quality_ok"]


@pytest.mark.slow
def test_full_suite_claims_no_wrong_row():
    bad = []
    for c in hs.all_cases():
        if c.conditional:          # Cd conditional on the stated air by design (reported apart)
            continue
        r = hs.run_case(c)
        assert "error" not in r, (c.id, r.get("error"))
        if r["determined_wrong"] and not r["conditional"]:
            bad.append(f"{c.id}: {r['determined_wrong']}/{r['determined']} (worst z {r['worst_z_wrong']:.1f})")
    assert not bad, "; ".join(bad)


#: a warm day (+15 K, undeclared) under winds that step at 6 km downrange: the user names the
#: wind profile only, and the misfit the temperature leaves must still keep every claim honest
USER_WITH_CASE = "pbc-wind_profile-42"


def test_effects_the_user_names_leave_a_misfit_that_is_still_checked():
    from acceptance import cases as wcases

    c = next(c for c in wcases.PROFILE_CASES if c.id == USER_WITH_CASE)
    r = hs.run_case(hs.HonestyCase(f"w-{c.id}", "withheld", seed=c.seed, withheld=c), with_effects=("wind_profile",))
    assert "error" not in r, r.get("error")
    assert r["effects_added"] == ["wind_profile"]
    # before the check ran on named effects: 62 of 118 determined rows wrong, up to 53 band sd
    assert r["determined_wrong"] == 0, (f"{r['determined_wrong']} of {r['determined']} determined rows wrong "
                                        f"(worst {r['worst_z_wrong']:.1f} band sd)")


def test_reseeded_cases_are_other_flights_of_the_same_kinds():
    """``--reseed K`` judges flights nobody tuned on: every case gets a new seed and id, its
    effect's size is scaled by 0.6-1.4 and its elevation moved by at most 4 deg; the same K gives
    the same flights."""
    base = hs.all_cases()
    a, b = hs.reseeded(base, 1), hs.reseeded(base, 1)
    assert [c.id for c in a] == [c.id for c in b] and [c.params for c in a] == [c.params for c in b]
    for old, new in zip(base, a):
        assert new.id == f"{old.id}-r1" and new.seed != old.seed
        if old.withheld is not None:
            w0, w1 = old.withheld, new.withheld
            assert w1.seed != w0.seed and abs(w1.elevation - w0.elevation) <= 4.0
            for k in ("wx", "wy", "dT", "dt"):
                if w0.params.get(k):
                    assert 0.6 <= w1.params[k] / w0.params[k] <= 1.4, (old.id, k)
        else:
            assert abs(new.params["qe"] - old.params["qe"]) <= 4.0
    assert [c.seed for c in hs.reseeded(base, 2)] != [c.seed for c in a]


#: reseeded flights that claimed wrong rows and no longer do: AR(1) speed noise of rho 0.95 with a
#: 2.4/2.7 m/s wind (8 rows, 5.2 sd, before the restricted-likelihood noise), a 155 mm 6-DOF flight
#: in a 10 m/s head wind at QE 8.8 (72 rows, 7.2 sd, before the close alternative's model error), a
#: 105 mm 6-DOF flight launched with 3 deg of yaw at QE 35.4 (4 rows 3-4 % high, 4.1 sd, before the
#: assumed launch yaw of a shell whose lift the track shows), and two flights of AR(1) noise of rho
#: 0.9 with no effect (one row each, 2.5 % at 3.08 sd and 2.7 % at 3.02 sd, the speed's correlation
#: estimated at 0.86 and 0.876, before the bands averaged over it: docs/ml.md, "The noise model's
#: own uncertainty")
FIXED_MISSES = [(1, "w-pm-wind-04-r1"), (2, "w-6dof-wind-31-r2"), (1, "w-6dof-null-201-r1"),
                (2, "w-pm-null-101-r2"), (6, "w-pm-null-109-r6")]


@pytest.mark.slow
@pytest.mark.parametrize("draw, cid", FIXED_MISSES)
def test_fixed_misses_of_the_reseeded_draws_stay_fixed(draw, cid):
    case = next(c for c in hs.reseeded(hs.all_cases(), draw) if c.id == cid)
    r = hs.run_case(case)
    assert r["determined_wrong"] == 0, f"{cid}: {r['determined_wrong']} wrong (worst z {r['worst_z_wrong']:.1f})"
