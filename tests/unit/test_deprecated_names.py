"""The names "summary" gave up (it means a result's printable table only) still work for one
release: the old module paths re-export the renamed functions, and the renamed attributes warn."""
import numpy as np
import pytest


def test_the_old_module_paths_give_the_renamed_functions():
    from bayesdrag.diagnosis.summary import console_summary, summary_paragraph
    from bayesdrag.planning.summary import summary_paragraph as plan_summary
    from bayesdrag.planning.plan import plan_paragraph
    from bayesdrag.results.words import diagnosis_lines, diagnosis_paragraph

    assert summary_paragraph is diagnosis_paragraph and console_summary is diagnosis_lines
    assert plan_summary is plan_paragraph


def test_an_unknown_name_is_still_an_attribute_error():
    import bayesdrag.results.words as words

    with pytest.raises(AttributeError, match="no attribute 'no_such_line'"):
        words.no_such_line


def test_a_diagnosis_summary_is_its_record_with_a_warning():
    from bayesdrag.diagnosis import Diagnosis

    rec = {"verdict": []}
    d = Diagnosis(rec, np.zeros(2), ("x",), {"x": 1.0}, np.zeros((2, 1)), None, np.zeros(2), np.ones((2, 1)), None)
    with pytest.warns(DeprecationWarning, match="Diagnosis.record"):
        assert d.summary is rec


@pytest.mark.parametrize("module, old, new", [
    ("bayesdrag.results.words", "summary_line", "outcome_line"),
    ("bayesdrag.pipeline", "summary_line", "outcome_line"),
    ("bayesdrag.pipeline.result", "ml_summary", "ml_record"),
    ("bayesdrag.commands.session", "session_summary", "session_lines"),
    ("bayesdrag.commands.batch", "summarise", "say_done"),
    ("bayesdrag.estimate.bayes.chain_diagnostics", "summarize", "convergence_table"),
    ("bayesdrag.estimate.bayes.sampler", "summarize", "convergence_table"),
])
def test_a_renamed_function_answers_to_its_old_name_with_a_warning(module, old, new):
    import importlib

    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=f"{old} is now {new}"):
        assert getattr(mod, old) is getattr(mod, new)
