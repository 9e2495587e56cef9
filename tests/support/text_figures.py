"""Check that every number a text prints is a value of a JSON document (the diagnosis paragraph
and console lines against ``diagnosis.json``)."""
from __future__ import annotations

import re

#: a number standing on its own: not part of a name (chi2, wx_1, s3, X0_muzzle)
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w.]*\w)")


def json_numbers(doc):
    """Every number (int or float, bools excluded) anywhere in a JSON document."""
    out = []
    if isinstance(doc, dict):
        for v in doc.values():
            out += json_numbers(v)
    elif isinstance(doc, list):
        for v in doc:
            out += json_numbers(v)
    elif isinstance(doc, (int, float)) and not isinstance(doc, bool):
        out.append(float(doc))
    return out


def _significant(token):
    mant = token.lstrip("+-").split("e")[0].split("E")[0]
    digits = mant.replace(".", "").lstrip("0")
    return max(len(digits), 1)


def unmatched_numbers(text, doc):
    """The numbers of ``text`` that no value of ``doc`` gives when rounded to the digits printed
    (empty: every figure is the JSON's).

    Parameters
    ----------
    text : str
    doc : dict
        The JSON document (as loaded).

    Returns
    -------
    list of str
    """
    values = json_numbers(doc)
    bad = []
    for m in NUMBER.finditer(text):
        tok = m.group(0)
        x = float(tok)
        sig = _significant(tok)
        if not any(float(f"{v:.{sig}g}") == x for v in values):
            bad.append(tok)
    return bad
