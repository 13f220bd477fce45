"""`go2vlm houses show` and `--world house:SEED`, as real processes: the plan as a PNG, bad input as one
line and exit 2 (a seed out of range, more rooms than fit, a house file edited by hand that no longer
loads), and the simulated Go2 standing in a generated house."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from busutil import GO2VLM, env


@pytest.fixture(autouse=True)
def _cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def _run(*args: str, timeout: float = 180) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*GO2VLM, *args], capture_output=True, text=True, timeout=timeout, env=env(), stdin=subprocess.DEVNULL
    )


def test_houses_show_writes_the_plan(tmp_path: Path) -> None:
    png = tmp_path / "plan.png"
    out = _run("houses", "show", "3", "--out", str(png))
    assert out.returncode == 0, out.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "seed 3 hash" in out.stdout and "teddy_bear (" in out.stdout
    world = next(line.split(": ", 1)[1] for line in out.stdout.splitlines() if "world file:" in line)
    assert Path(world).is_relative_to(tmp_path / "cache"), "generated houses go to the cache, not the package"


def test_bad_input_is_one_line_and_exit_2(tmp_path: Path) -> None:
    good = _run("houses", "show", "4", "--out", str(tmp_path / "p.png"))
    assert good.returncode == 0, good.stderr
    world = Path(next(line.split(": ", 1)[1] for line in good.stdout.splitlines() if "world file:" in line))
    edited = tmp_path / "edited.xml"
    edited.write_text(world.read_text().replace('type="mesh"', 'type="meshh"', 1))
    cases = [
        (["houses", "show", "-5"], "out of range"),
        (["houses", "show", "3", "--rooms", "12"], "12 rooms do not fit"),
        (["houses", "show", str(edited)], "does not load"),
        (["sim", "--world", "house:-1", "--duration", "0.1"], "out of range"),
        (["sim", "--world", str(edited), "--duration", "0.1"], "meshh"),
        (
            [
                "demo",
                "--world",
                "house:3:rooms=9",
                "--goal",
                "go to the mug",
                "--no-video",
                "--out",
                str(tmp_path / "d"),
            ],
            "9 rooms do not fit",
        ),  # fmt: skip
    ]
    for args, fragment in cases:
        out = _run(*args)
        assert "Traceback" not in out.stderr, out.stderr
        assert out.returncode == 2, (args, out.stderr)
        errors = [line for line in out.stderr.splitlines() if line.startswith("go2vlm")]
        assert len(errors) == 1 and fragment in errors[0], (args, out.stderr)


def test_the_sim_runs_in_a_house() -> None:
    out = _run("sim", "--world", "house:3", "--mode", "kinematic", "--fast", "--duration", "1.0", timeout=300)
    assert out.returncode == 0, out.stderr
    assert "world 'house:3'" in out.stderr and "stopped at sim time" in out.stderr
