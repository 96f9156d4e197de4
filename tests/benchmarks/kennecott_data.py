"""Where the benchmarks read the real Kennecott blastholes: ``BGM_KENNECOTT``, else ``../shared/data`` beside the repository.

The same place as the tests' (``tests/conftest.py``). The data are never copied into the repository: a benchmark
that finds nothing there says so and goes on without them.
"""

from __future__ import annotations

import os
from pathlib import Path

KENNECOTT = Path(
    os.environ.get(
        "BGM_KENNECOTT",
        Path(__file__).resolve().parents[3] / "shared" / "data" / "kennecott-blastholes" / "blastholes_tagged.csv",
    )
)
