"""The sentences the console, the report and summary() share (bayesdrag.results.words): the
determined range with its holes, never a zero-width interval (issue 47, item 3)."""
from bayesdrag.results.words import determined_words, mach_interval


def test_a_one_row_hole_reads_as_one_mach_number():
    assert mach_interval(1.05, 1.05) == "1.05"
    assert mach_interval(1.0499, 1.0501) == "1.05"        # rounds to one number
    assert mach_interval(1.00, 1.03) == "1.00-1.03"


def test_the_range_names_its_holes():
    undetermined = [[0.80, 0.89], [1.00, 1.03], [1.05, 1.05], [1.07, 1.07], [2.35, 2.40]]
    assert (determined_words([0.894, 2.34], undetermined)
            == "Mach 0.89-2.34 except 1.00-1.03, 1.05, 1.07")   # the ends outside the range are not holes
    assert determined_words([0.894, 2.34], []) == "Mach 0.89-2.34"
    assert determined_words(None, undetermined) == "nowhere"
    assert determined_words([0.894, 2.34], [[1.0, 1.03]], digits=3) == "Mach 0.894-2.340 except 1.000-1.030"


def test_diagnosis_lines_and_report_say_the_same(tmp_path):
    """One fit's determined range in the console line, summary() and the report, in the same words."""
    import bayesdrag
    from bayesdrag.pipeline import outcome_line
    from fixtures import met_flight as M

    tp, rp = M.write_icao_case(tmp_path, seed=9)          # the independent integrator's flight
    res = bayesdrag.fit(bayesdrag.read_track(tp), bayesdrag.read_round(rp), mcmc=False, model_check=False)
    ml = res.record["ml"]
    words = determined_words(ml["mach_range_determined"], ml["quality"].get("undetermined", []))
    assert f"Cd determined over {words}" in outcome_line(res)
    assert words in str(res.summary())
    res.write(tmp_path / "out")
    assert f"Cd determined over {words}." in (tmp_path / "out" / "report.html").read_text()
