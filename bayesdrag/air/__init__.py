"""The air a shell flies through: the ICAO standard atmosphere and measured met profiles
(:mod:`.atmosphere`), winds that change by height or by downrange distance (:mod:`.wind`), and
the air at the gun as a weather meter gives it (:mod:`.station`)."""
