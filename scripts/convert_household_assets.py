"""Copy the household world's meshes and textures out of pybullet's `pybullet_data` (offline, once).

    pip install pybullet            # only for this script: go2vlm never imports it
    python scripts/convert_household_assets.py [--out src/go2vlm/sim/assets/household]

Each mesh is turned z-up, scaled to metres, moved so that its footprint is centred on the origin and
its lowest point is at z = 0, and written as a plain OBJ (v, vt, f; no materials: the world file
gives each its MuJoCo material), with 4 decimals, which MuJoCo loads directly. Textures become PNGs
of at most 256 pixels a side. Licences and origins: LICENSES.md beside the assets (written here).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

OUT = Path(__file__).resolve().parents[1] / "src/go2vlm/sim/assets/household"


@dataclass(frozen=True)
class Asset:
    name: str  # file stem in the repo
    source: str  # path inside pybullet_data
    height_m: float  # the mesh is scaled to this height
    euler_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # x, y, z rotation to make it z-up
    texture: str | None = None  # path inside pybullet_data
    flip_v: bool = False


ASSETS = (
    Asset("teddy_bear", "teddy2_VHACD_CHs.obj", 0.42, (90, 0, 0)),
    Asset("duck", "duck.obj", 0.30, (90, 0, 0), texture="duckCM.png"),
    Asset("soccer_ball", "soccerball.obj", 0.22, texture="colors16.png"),
    Asset("mug", "objects/mug.obj", 0.20, (90, 0, 0)),
    Asset("lego_brick", "lego/lego.obj", 0.16),
    Asset("tray", "tray/tray_textured.obj", 0.07, texture="tray/tray.jpg"),
    Asset("table_top", "table/table.obj", 1.0, texture="table/table.png"),
    Asset("cone", "racecar/meshes/cone.obj", 0.32),
    Asset("toy_chest", "jenga/jenga.obj", 1.0),
)


def _rot(euler_deg: tuple[float, float, float]) -> np.ndarray:
    ax, ay, az = (math.radians(a) for a in euler_deg)
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    return rz @ ry @ rx


def convert_obj(src: Path, dst: Path, asset: Asset) -> tuple[int, tuple[float, float, float]]:
    """Write the transformed OBJ; (faces, half extents x, y and the height) in metres."""
    verts: list[list[float]] = []
    uvs: list[list[float]] = []
    faces: list[list[tuple[int, int | None]]] = []
    for line in src.read_text(errors="ignore").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append([float(x) for x in parts[1:4]])
        elif parts[0] == "vt":
            uvs.append([float(x) for x in parts[1:3]])
        elif parts[0] == "f":
            face = []
            for p in parts[1:]:
                idx = p.split("/")
                vi = int(idx[0])
                ti = int(idx[1]) if len(idx) > 1 and idx[1] else None
                face.append((vi if vi > 0 else len(verts) + vi + 1, ti if ti is None or ti > 0 else len(uvs) + ti + 1))
            for k in range(1, len(face) - 1):  # triangles
                faces.append([face[0], face[k], face[k + 1]])
    v = np.array(verts) @ _rot(asset.euler_deg).T
    lo, hi = v.min(axis=0), v.max(axis=0)
    scale = asset.height_m / (hi[2] - lo[2])
    v = (v - np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])) * scale
    use_uv = asset.texture is not None and uvs
    lines = [f"# {asset.name}: from pybullet_data/{asset.source} (scripts/convert_household_assets.py)"]
    lines += [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in v]
    if use_uv:
        lines += [f"vt {u:.4f} {1 - t if asset.flip_v else t:.4f}" for u, t in uvs]
    for f in faces:
        if use_uv and all(t is not None for _, t in f):
            lines.append("f " + " ".join(f"{vi}/{ti}" for vi, ti in f))
        else:
            lines.append("f " + " ".join(str(vi) for vi, _ in f))
    dst.write_text("\n".join(lines) + "\n")
    ext = v.max(axis=0)
    return len(faces), (round(float(ext[0]), 3), round(float(ext[1]), 3), round(float(ext[2]), 3))


def convert_texture(src: Path, dst: Path, side: int = 256) -> tuple[int, int]:
    img = Image.open(src).convert("RGB")
    img.thumbnail((side, side), Image.Resampling.LANCZOS)
    img.save(dst, optimize=True)
    return img.size


LICENSES = """# Household assets: origin and licence

Every file here was made by `scripts/convert_household_assets.py` from pybullet's `pybullet_data`
(PyPI package `pybullet` 3.2.7, the data folder of the bullet3 repository). pybullet and its data are
distributed under the **zlib licence** (bullet3's LICENSE.txt, PyPI `License: zlib`): "This software
is provided 'as-is' ... Permission is granted to anyone to use this software for any purpose,
including commercial applications, and to alter it and redistribute it freely", provided that the
origin is not misrepresented and altered versions are marked as such. These files are altered
versions (z-up, scaled to metres, re-centred, materials dropped, 4 decimals; textures resized to at
most 256 px and saved as PNG).

| file | origin in pybullet_data | notes |
|---|---|---|
{rows}

Upstream notes, as far as they are known: `duck.obj`/`duckCM.png` looks like the COLLADA "Duck"
sample model (Sony Computer Entertainment Inc.), which the COLLADA and glTF sample collections publish
under the SCEA Shared Source License 1.0; pybullet ships it under zlib without a notice of its own, so
check the SCEA terms before redistributing the duck outside go2vlm. The other meshes ship in bullet3's
data folder without a separate licence file (the `jenga` and `domino` models beside them say "created
by Erwin Coumans"), so bullet3's zlib licence applies.
No file here is downloaded at run time.
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    import pybullet_data

    data = Path(pybullet_data.getDataPath())
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for a in ASSETS:
        faces, ext = convert_obj(data / a.source, args.out / f"{a.name}.obj", a)
        note = f"{faces} triangles; half extents x, y and height {ext} m"
        rows.append(f"| `{a.name}.obj` | `{a.source}` | {note} |")
        if a.texture:
            size = convert_texture(data / a.texture, args.out / f"{a.name}.png")
            rows.append(f"| `{a.name}.png` | `{a.texture}` | texture, {size[0]}x{size[1]} |")
        print(a.name, faces, ext)
    (args.out / "LICENSES.md").write_text(LICENSES.format(rows="\n".join(rows)))


if __name__ == "__main__":
    main()
