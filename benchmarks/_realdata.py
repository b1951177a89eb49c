"""Where the benchmarks find the recorded data sets.

The project's recorded data live in ``shared/realdata`` beside the repository; set
``FUSION_REALDATA`` to another folder to use a copy elsewhere.
"""

from __future__ import annotations

import os
from pathlib import Path

REALDATA = Path(os.environ.get("FUSION_REALDATA",
                               Path(__file__).resolve().parents[2] / "shared" / "realdata"))
AUTOFERRY = REALDATA / "autoferry_sensor_fusion"
