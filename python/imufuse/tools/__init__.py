"""The tools around the filters, on the floor of the sessions (docs/architecture.md): each
reads the catalogue and runs filters, none is imported below this floor.

  demo        `imufuse demo`: every filter on simulated motion, compiled against its twin
  arduino     `imufuse export arduino`: csrc/ as an Arduino library with its examples
  stubs       `python -m imufuse.tools.stubs > imufuse_c/__init__.pyi`: the compiled
              package's type stubs, generated from the catalogue
"""
