# SPDX-License-Identifier: Apache-2.0
"""Shared set-up: the `toonforce` program to compare with (TOONFORCE_CLI, set by CTest) and the
source tree's scenes (TOONFORCE_SOURCE_DIR)."""
import os
import pathlib

import pytest


@pytest.fixture(scope="session")
def cli() -> str:
    path = os.environ.get("TOONFORCE_CLI")
    if not path or not os.access(path, os.X_OK):
        pytest.fail("TOONFORCE_CLI must name the toonforce program built with this module (CTest sets it)")
    return path


@pytest.fixture(scope="session")
def root() -> pathlib.Path:
    return pathlib.Path(os.environ.get("TOONFORCE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[3]))
