"""The commands: what ``bayesdrag fit | diagnose | simulate | batch | demo`` do, as functions of
objects (the Python API) and of files (the command line). :mod:`.options` holds every option
and its default once; :mod:`bayesdrag.cli` only parses arguments into options and maps errors to
exit codes."""
