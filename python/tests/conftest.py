"""Shared cases of the Python tests."""

import numpy as np
import pytest


def torus_fields(n=64, h=1.0, R=18.0, r=7.0):
    """A distorted torus: the exact signed distance of a torus around z and a field with
    the same zero set that is far from a distance (scaled by a smooth positive factor)."""
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float64)
    c = (n - 1) / 2
    X, Y, Z = (x - c) * h, (y - c) * h, (z - c) * h
    exact = np.sqrt((np.sqrt(X**2 + Y**2) - R) ** 2 + Z**2) - r
    factor = (1 + 0.5 * np.sin(X / 7) * np.cos(Y / 5) + 0.3 * Z / (n * h)) * np.exp(0.02 * X)
    return exact * factor, exact


@pytest.fixture(scope="session")
def torus():
    return torus_fields()


def sphere_field(n, radius, h=1.0, center=None):
    """Signed distance to a sphere on an n³ array indexed [z, y, x], world = index·h."""
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float64) * h
    c = (n - 1) / 2 * h if center is None else center
    return np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2) - radius
