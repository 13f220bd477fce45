"""The Go2's L1 lidar in MuJoCo: a ring of rays cast with mj_multiRay from the lidar's mount.

Pure (no DDS). `Lidar.scan(data)` returns the hit points in the lidar frame (the profile's lidar frame, the
frame of the real rt/utlidar/cloud), so that the sim publishes the cloud a real Go2 does and the same
`geometry/scan.py` code turns either into /scan.

The real L1 covers 360 x 90 degrees with ~21600 points/s. The sim casts a cheap subset: `azimuths`
rays around (2 degrees apart by default) on each of the `ELEVATIONS` rows (degrees above the base's
horizontal plane): the rows below the horizon reach the floor from 0.27 m ahead of the lidar out to
~1.3 and ~2.6 m, so the cloud is never empty while the sensor works and a low object near the robot
stays in /scan (a 0.16 m lego brick from 0.11 m ahead of the lidar on; with -12 degrees the lowest
row, rays passed over it from 0.53 m in, the map cleared it and the robot walked over it). The
rows steeper than -12 degrees (`LOW_ROWS` of them, down to -45) look forward only, as the
chin-mounted L1 does (behind, the body is in their way), and are spaced evenly in tan(elevation):
a row meets a plane at a height z at (lidar height - z) / tan ahead, so with consecutive tans at
most (h - 0.04) / (h - 0.07) = 1.15 apart (h = 0.27 m, the lidar off the floor) some row meets any
face from /scan's 4 cm band bottom to 7 cm high, at any distance it covers: a 7 cm tray's rim stays
in /scan from 1.4 m in (with rows at -20, -30 and -45 only, it flickered out at 0.6, 0.9 and 1.3 m,
each free ray cleared it from the map, and the robot walked into it). /scan measures its band from
the floor (`stance`: geometry/scan.py), so that the floor these rows meet is never an obstacle,
lying down included. The horizon row sees walls, and those above see what overhangs:
a table top 0.21 m above the lidar (0.48 m off the floor) is met by the +8 row from 1.5 m, the +15
row from 0.8 m and the +30 row from 0.36 m away, so the edge of a table stays in /scan as the robot
comes near it (with only +8, rays passed under it from 1.5 m on, the map cleared the space under it,
and footprints met tabletops). The real L1's 90 degrees of elevation hold these rows and more.
The robot's own geoms (groups 2 and 3, sim/go2_model.py) are not hit: real clouds of the legs are
left out of /scan by the self box instead.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from go2vlm.geometry.scan import Stance, mount_transform
from go2vlm.robot_profile.go2 import GO2

__all__ = ["ELEVATIONS", "Lidar"]

NEAR_ROWS_BELOW = -12.0  # rows steeper than this look forward only (behind, the body is in their way)
LOW_ROWS = 12  # from -45 degrees up to NEAR_ROWS_BELOW, evenly in tan: (tan 45 / tan 12)^(1/12) = 1.14
_LO, _HI = math.tan(math.radians(-NEAR_ROWS_BELOW)), math.tan(math.radians(45.0))
ELEVATIONS = (
    *(-math.degrees(math.atan(_LO * (_HI / _LO) ** (k / LOW_ROWS))) for k in range(LOW_ROWS, 0, -1)),
    NEAR_ROWS_BELOW, -6.0, 0.0, 8.0, 15.0, 22.0, 30.0, 40.0,
)  # fmt: skip  # degrees
CUTOFF = 10.0  # m: beyond this a ray returns nothing (the scan's range_max)
_GEOMGROUP = np.array([1, 1, 0, 0, 1, 1], dtype=np.uint8)  # not the robot's groups 2 and 3


class Lidar:
    def __init__(self, model: mujoco.MjModel, base_body: int, azimuths: int = 180) -> None:
        self.model = model
        self.base = base_body
        az = np.linspace(-math.pi, math.pi, azimuths, endpoint=False)
        rows = []
        for deg in ELEVATIONS:
            el, a = math.radians(deg), az if deg >= NEAR_ROWS_BELOW else az[np.cos(az) >= 0.0]
            rows.append(np.column_stack([np.cos(el) * np.cos(a), np.cos(el) * np.sin(a), np.full_like(a, np.sin(el))]))
        self.dirs_base = np.vstack(rows)  # unit rays in the base frame
        self.mount_r, self.mount_t = mount_transform(GO2.lidar.pos, GO2.lidar.pitch)
        n = len(self.dirs_base)
        self._geomid = np.zeros(n, dtype=np.int32)
        self._dist = np.zeros(n, dtype=np.float64)

    @property
    def rays(self) -> int:
        return len(self.dirs_base)

    def scan(self, data: mujoco.MjData) -> np.ndarray:
        """Hit points (N, 3) in the lidar frame, at the pose in `data` (kinematics must be current)."""
        rb = data.xmat[self.base].reshape(3, 3)
        origin = data.xpos[self.base] + rb @ self.mount_t
        vec = np.ascontiguousarray((self.dirs_base @ rb.T).reshape(-1))
        n = self.rays
        mujoco.mj_multiRay(
            self.model, data, origin, vec, _GEOMGROUP, True, -1, self._geomid, self._dist, None, n, CUTOFF
        )
        hit = (self._geomid >= 0) & (self._dist >= 0) & (self._dist <= CUTOFF)
        p_base = self.dirs_base[hit] * self._dist[hit, None]  # from the mount, in base axes
        return p_base @ self.mount_r  # base axes -> lidar frame (R^T p, row-wise)

    def stance(self, data: mujoco.MjData) -> Stance:
        """The base's attitude and height above the floor (the worlds' floor is z = 0), for /scan's band."""
        return Stance.of(data.xmat[self.base].reshape(3, 3), float(data.xpos[self.base][2]))
