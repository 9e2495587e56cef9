"""Figures: every function takes ``ax=`` (or ``fig=``) and returns what it drew on; no physics,
no files (the report and command layers save them)."""
