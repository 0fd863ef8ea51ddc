"""Locating and running the SUMO tools installed from PyPI (eclipse-sumo, libsumo, sumolib).

Every SUMO command the factory runs goes through `run_tool`, so a failing netconvert or a missing
install surfaces as one `SynthError` naming the tool and its own error lines.

See docs/data.md.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

from langtraj.errors import LangTrajError

STEP_LENGTH = 0.1
"""Simulation step in seconds: the scenario step, so every SUMO step is one scenario step."""


class SynthError(LangTrajError):
    """SUMO is missing, or a SUMO tool or simulation failed."""


@lru_cache(maxsize=1)
def sumo_home() -> Path:
    """SUMO_HOME of the PyPI `eclipse-sumo` package (or of the environment variable when set)."""
    env = os.environ.get("SUMO_HOME")
    if env and (Path(env) / "bin").is_dir():
        return Path(env)
    try:
        import sumo
    except ImportError:
        raise SynthError(
            "SUMO is not installed: pip install 'eclipse-sumo==1.28.*' 'libsumo==1.28.*' 'sumolib==1.28.*'"
        ) from None
    return Path(sumo.SUMO_HOME)


def tool_path(name: str) -> Path:
    """Path of a SUMO binary (`sumo`, `netconvert`, `netgenerate`, ...)."""
    path = sumo_home() / "bin" / name
    if not path.exists():
        raise SynthError(f"SUMO tool {name!r} not found in {path.parent}")
    return path


@lru_cache(maxsize=1)
def sumo_version() -> str:
    """The version string of the SUMO library used for simulation, e.g. 'SUMO 1.28.0'."""
    import libsumo

    return str(libsumo.getVersion()[1])


def run_tool(name: str, args: Sequence[str | os.PathLike[str]], cwd: Path | None = None) -> str:
    """Run a SUMO binary; return its stdout. A non-zero exit raises SynthError with its last lines."""
    cmd = [str(tool_path(name)), *(str(a) for a in args)]
    env = {**os.environ, "SUMO_HOME": str(sumo_home())}
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-8:])
        raise SynthError(f"{name} failed (exit {proc.returncode}): {tail}")
    return proc.stdout


def simulation_options(
    net_file: Path,
    route_files: Sequence[Path],
    *,
    seed: int,
    end_s: float,
    lanechange_output: Path | None = None,
    additional_files: Sequence[Path] = (),
) -> list[str]:
    """Command-line options of every factory simulation (values measured to work; see docs/data.md).

    Sublane model at 0.8 m (SUMO's default instant lane change jumps a lane width in one step), IDM
    car following (driver imperfection sigma is set to 0 in the vehicle types), junction collision
    checks that warn instead of removing vehicles (the window filter drops affected windows), striping
    pedestrians, collisions only on physical overlap. A vehicle stuck for 90 s is teleported (SUMO's
    deadlock breaker); the window filter drops windows with a teleport.
    """
    options = [
        "--net-file", str(net_file),
        "--route-files", ",".join(str(p) for p in route_files),
        "--step-length", f"{STEP_LENGTH}",
        "--begin", "0",
        "--end", f"{end_s:.1f}",
        "--seed", str(int(seed)),
        "--lateral-resolution", "0.8",
        "--carfollow.model", "IDM",
        "--pedestrian.model", "striping",
        "--collision.check-junctions", "true",
        "--collision.action", "warn",
        "--collision.mingap-factor", "0",
        "--time-to-teleport", "90",
        "--max-depart-delay", "20",
        "--default.action-step-length", f"{STEP_LENGTH}",
        "--no-step-log", "true",
        "--no-warnings", "true",
        "--duration-log.disable", "true",
    ]  # fmt: skip
    if additional_files:
        options += ["--additional-files", ",".join(str(p) for p in additional_files)]
    if lanechange_output is not None:
        options += ["--lanechange-output", str(lanechange_output)]
        options += ["--lanechange-output.started", "true", "--lanechange-output.ended", "true"]
    return options
