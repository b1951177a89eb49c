"""A written window (the result-JSON form the recording-level speed and position steps read),
built from true delays and solved on the sensors and speed the localizer is given."""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from factors.tdoa.model import predicted_tdoas


def written_window(p_true, t0, pairs, *, true_sensors, sensors, c_true=1500.0, c_file=1500.0,
                   sigma_s=1e-7):
    """One window whose one source owns the delays of `pairs` at `true_sensors` and `c_true`,
    its fix solved on `sensors` at `c_file`."""
    q = np.array(pairs)
    taus = predicted_tdoas(p_true, true_sensors, q, c=c_true)
    start = least_squares(lambda x: (predicted_tdoas(x, sensors, q, c=c_file) - taus) * 1e6,
                          p_true).x
    tdoas = [{"pair": list(pr), "tau": float(t), "t": t0 + 6.0, "rate": 0.0, "valid": True,
              "llr": 5.0, "sigma": sigma_s} for pr, t in zip(pairs, taus, strict=True)]
    src = {"x": start[0], "y": start[1], "z": start[2], "cov": np.eye(3).tolist(),
           "tdoas_used": len(pairs), "observable": True, "mirror_ambiguous": False,
           "owned_tdoas": list(range(len(pairs))), "paths": ["direct"] * len(pairs)}
    return {"t_start": t0, "t_end": t0 + 12.0, "tdoas": tdoas, "sources": [src]}
