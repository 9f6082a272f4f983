"""Shared fixtures (the generators they use are in :mod:`tests.strategies`)."""

from __future__ import annotations

import pytest

from tests.strategies import three_views


@pytest.fixture(scope="session")
def team_views():
    return three_views(3)
