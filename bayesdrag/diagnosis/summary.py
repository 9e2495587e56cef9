"""Deprecated: the diagnosis's sentences moved to :mod:`bayesdrag.results.words` (``summary_paragraph`` is now ``diagnosis_paragraph``, ``console_summary`` is ``diagnosis_lines``); this re-export is removed in release 0.3."""

_RENAMED = {"summary_paragraph": "diagnosis_paragraph", "console_summary": "diagnosis_lines"}


def __getattr__(name):
    from ..results import words   # imported when asked: results/ sits above diagnosis/

    return getattr(words, _RENAMED.get(name, name))
