"""HTML reports: self-contained (figures embedded as base64 PNG, no external files, scripts or
fonts), so a report opens offline and can be mailed as one file. :mod:`.render` holds the one
jinja2 environment and the one figure-embedding helper; :mod:`.fit`, :mod:`.diagnosis` and
:mod:`.campaign` build each report's context. No physics and no fitting here."""
