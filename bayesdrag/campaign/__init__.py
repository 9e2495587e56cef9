"""Campaigns: pooling many rounds of one shell (:mod:`.pooling`) and simulated campaigns
(:mod:`.synthetic`); running the rounds is :mod:`bayesdrag.commands.batch`."""
