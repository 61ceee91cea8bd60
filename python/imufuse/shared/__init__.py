"""The lowest floor of the package: the helpers every floor above shares, importing nothing of
imufuse but each other and imufuse.rotations (docs/architecture.md).

  checks      one validation path for both backends: dtype, dt, reals in range, run inputs
  estimate    the estimate adapters: a filter's state read as a quaternion, angles or an angle
  recovery    the recovery budgets of the catalogue: samples to come back after hostile input
  bits        bit patterns, ULP distances and exact C literals of float32/float64 values
  cproto      the C-prototype and struct reader (setup.py's binding generator loads it by path)
  atomic      files written whole or not at all, and the lock of a read-merge-write
  jsonfile    the one reader of the JSON files a user hands in (bounded size and nesting)
  resources   the files the installed package carries (csrc/, the MCU harness data)
  plotaxes    the figures' axis helpers (imufuse.plots draws with them)
"""
