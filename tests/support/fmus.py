"""Which FMUs the long statistical tests run on.

Their subject is the loop's numbers over many steps (a cost rate against its prediction, a
formation held for minutes), not the pythonfmu adapters: with a C compiler they run the
linear components as native FMUs (the compiled master where every component has one),
which give the pythonfmu FMUs' traces to 1e-12 of each signal's scale
(tests/test_compare_composition.py, tests/test_native.py hold that), in a fraction of the
time. Without a compiler they run on pythonfmu FMUs, as before.
"""
from __future__ import annotations

import os
import shutil

#: "native" where a C compiler is found ($CC, else cc), else "python"
LONG_RUN_FMUS = "native" if shutil.which(os.environ.get("CC", "cc")) else "python"
