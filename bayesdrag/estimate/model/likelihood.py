"""The likelihoods a fit can use, by name, and the Student-t's default degrees of freedom.

Kept apart from the problem's numerics so that the option parser can name them without importing
the compiled AR(1) filter."""
from __future__ import annotations

__all__ = ["LIKELIHOODS", "STUDENT_T_NU"]

#: ``gaussian``: independent normal noise (AR(1) per channel where chosen); ``student-t``:
#: heavy-tailed noise that down-weights outliers
LIKELIHOODS = ("gaussian", "student-t")
#: degrees of freedom of the Student-t likelihood unless given: heavy tails, finite variance
STUDENT_T_NU = 4.0
