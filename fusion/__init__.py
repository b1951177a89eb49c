"""sonar-fusion: probabilistic sensor fusion for underwater acoustics on factor graphs.

Sub-packages group the pipelines: :mod:`fusion.passive` (narrowband acquisition, bearing
tracking, track quality, crossings, smoothing, target motion analysis), :mod:`fusion.active`
(multistatic active tracking with fuzzy association), :mod:`fusion.simulate` (seeded scenario
generators). :mod:`fusion.io` reads and writes the file formats; :mod:`fusion.geometry` holds
angles, arrays and delays. Custom GTSAM factors live in the separate :mod:`factors` package.
"""

import logging

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())
