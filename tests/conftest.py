"""Shared fixtures: the default config and a seeded simulated drive with its analysis."""

from collections.abc import Callable
from pathlib import Path

import can
import pytest

from app.config import Config, load_config
from app.pipeline import Pipeline
from app.sim.simulated_drive import SimulatedDrive
from tests.simulated import REPO, cached_drive, run_pipeline


@pytest.fixture(scope="session")
def config() -> Config:
    return load_config()


@pytest.fixture(scope="session")
def drive() -> SimulatedDrive:
    return cached_drive()


@pytest.fixture(scope="session")
def analysed(config: Config, drive: SimulatedDrive) -> Pipeline:
    return run_pipeline(config, drive)


@pytest.fixture
def write_config(tmp_path: Path) -> Callable[..., Path]:
    """Write a config text into tmp_path; {dbc} stands for the repo's dbc/ folder."""

    def write(text: str, name: str = "car.toml") -> Path:
        path = tmp_path / name
        path.write_text(text.replace("{dbc}", str(REPO / "dbc")))
        return path

    return write


@pytest.fixture(scope="session")
def drive_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The seeded constant-radius drive (C2n 15.1) as a BLF log (a module may have its own)."""
    path = tmp_path_factory.mktemp("drive") / "drive.blf"
    with can.Logger(path) as writer:
        for m in cached_drive("constant_radius", 41, 15.1).messages:
            writer.on_message_received(m)
    return path
