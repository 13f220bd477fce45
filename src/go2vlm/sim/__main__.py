"""Tiny demo: ``python -m go2vlm.sim --world follow_ball --seconds 6 --out /tmp/go2sim``.

Walks the robot with a constant command (or a ground-truth ball follower with
``--follow``), prints the state once per second and saves head/world frames.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from go2vlm.sim import Go2Sim, SimConfig
from go2vlm.sim.ball import follow_command


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--world", default="follow_ball")
    ap.add_argument("--mode", default="dynamic", choices=["dynamic", "kinematic"])
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--cmd", type=float, nargs=3, default=[0.5, 0.0, 0.0], metavar=("VX", "VY", "VYAW"))
    ap.add_argument("--follow", action="store_true", help="steer towards the red ball (ground truth)")
    ap.add_argument("--out", type=Path, default=None, help="folder for PNG frames (1 per 0.5 s)")
    args = ap.parse_args()

    sim = Go2Sim(SimConfig(world=args.world, mode=args.mode, camera_width=640, camera_height=360))
    if args.out:
        import cv2

        args.out.mkdir(parents=True, exist_ok=True)
    sim.set_command(*args.cmd)
    for k in range(int(args.seconds * 10)):
        if args.follow and "red_ball" in sim.object_poses():
            cmd, _ = follow_command(sim, "red_ball")
            sim.set_command(*cmd)
        sim.advance(0.1)
        if k % 10 == 9:
            s = sim.state()
            print(
                f"t={s.time:5.1f} mode={s.mode:8s} pos={np.round(s.position, 2)} "
                f"rpy={np.round(s.imu_rpy, 2)} v_body={np.round(s.lin_vel_body, 2)}"
            )
        if args.out and k % 5 == 4:
            cv2.imwrite(str(args.out / f"head_{k:04d}.png"), sim.render_head()[:, :, ::-1])
            cv2.imwrite(str(args.out / f"world_{k:04d}.png"), sim.render_world_camera()[:, :, ::-1])
    sim.close()


if __name__ == "__main__":
    main()
