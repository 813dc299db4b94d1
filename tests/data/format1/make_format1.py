"""Write the format-1 files of ``tests/test_result_protocol.py`` with the code before the dataclass layout.

Usage, from the repository root (commit d7fe32b is the last with the hand-written layouts)::

    mkdir -p /tmp/sb_format1 && git archive d7fe32b src | tar -x -C /tmp/sb_format1
    PYTHONPATH=/tmp/sb_format1/src:. python tests/data/format1/make_format1.py

The instances come from ``tests/_support/result_builders.py``, as in the test.
"""

import sys
from pathlib import Path

import spiralbayes
from tests._support import result_builders as b

OUT = Path(__file__).parent
FILES = {"scan.h5": b.scan_result, "alternatives.h5": b.alternatives_result, "limits.h5": b.exclusion_limits,
         "completeness.h5": b.completeness_result, "posterior.h5": b.posterior_result}

if __name__ == "__main__":
    if not callable(spiralbayes.ScanResult.best) or hasattr(spiralbayes, "results"):
        sys.exit(f"{spiralbayes.__file__} is not the code before the dataclass layout: see this script's docstring")
    for name, build in FILES.items():
        build().save(OUT / name)
        print("wrote", OUT / name)
