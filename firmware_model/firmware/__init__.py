"""firmware: the 68000 assembly sources, assembling a build, and the harness that runs it on :mod:`isa`.
Imports runtime, spec, model and isa."""
