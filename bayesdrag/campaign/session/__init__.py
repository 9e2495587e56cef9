"""Chronograph sessions: the shots of one series fitted as one (docs/radar.md, "Chronograph sessions")."""
