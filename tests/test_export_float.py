"""Single-precision (`--float`) compensators against `stageid compensate`, on random models.

The measure (issue 17, point 3): the float drive lies within 1e-5 of the drive's range of the
package's double drive over the record.  A drive that does not move over the record (pinned at
a drive limit, or a held reference) has no range; its scale is then its magnitude, max |drive|:
float represents a constant only to 2**-24 of its size, so 1e-5 of it leaves room for a few
dozen roundings, as 1e-5 of the range does for a moving drive.  The measure for a moving drive
is the range alone, however small against the drive's magnitude.
"""

from __future__ import annotations

import numpy as np


def drive_scale(drive) -> float:
    """The range of ``drive`` (max - min), or max |drive| when the drive is constant."""
    drive = np.asarray(drive, dtype=float)
    span = float(np.ptp(drive))
    return span if span > 0.0 else float(np.max(np.abs(drive)))
