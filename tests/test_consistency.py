"""The NEES and the chi-square band of its average (quad_wrench_env/estimators/consistency.py), derived
here without the code under test: a closed form and a Monte-Carlo of Gaussian errors; and the ``nees``
part of ``quad-wrench compare estimators`` on a small config."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from quad_wrench_cli.consistency import weave
from quad_wrench_cli.main import main
from quad_wrench_env.estimators.consistency import average_nees_band, nees


def _even_chi2_cdf(x: float, dof: int) -> float:
    """``P(χ²_k <= x)`` for even k = 2m: the Erlang form ``1 - exp(-x/2) Σ_{j<m} (x/2)^j / j!``."""
    half, term, total = x / 2.0, 1.0, 0.0
    for j in range(dof // 2):
        total += term
        term *= half / (j + 1)
    return 1.0 - math.exp(-half) * total


def _even_chi2_quantile(p: float, dof: int) -> float:
    low, high = 0.0, 10.0 * dof + 100.0
    for _ in range(200):  # bisection on the monotone CDF
        middle = 0.5 * (low + high)
        low, high = (middle, high) if _even_chi2_cdf(middle, dof) < p else (low, middle)
    return 0.5 * (low + high)


@pytest.mark.parametrize(("runs", "dimension"), [(1, 2), (2, 1), (20, 3), (50, 3)])
def test_the_band_is_the_chi_square_quantiles_over_the_runs(runs, dimension):
    """M runs of a d-dimensional block: M·ε̄ ~ χ²(M·d), so the 95 % band is χ²_{Md}(0.025, 0.975)/M; for
    M·d = 2 it is ``-2 ln(0.975)/M`` to ``-2 ln(0.025)/M``, and for any even M·d the Erlang form's."""
    low, high = average_nees_band(runs, dimension)
    dof = runs * dimension
    expected = (_even_chi2_quantile(0.025, dof) / runs, _even_chi2_quantile(0.975, dof) / runs)
    assert (low, high) == pytest.approx(expected, rel=1e-9)
    if dof == 2:
        assert (low, high) == pytest.approx((-2 * math.log(0.975) / runs, -2 * math.log(0.025) / runs))


def test_the_average_nees_of_gaussian_errors_falls_in_the_band_95_percent_of_the_time():
    """20 000 draws of 20 runs of 3-dimensional Gaussian errors with a random covariance: the average
    NEES is inside the band in 95 % of the draws and above it in 2.5 %, within 4 binomial sd."""
    rng = np.random.default_rng(0)
    trials, runs, dimension = 20_000, 20, 3
    root = rng.normal(size=(dimension, dimension)) + 2.0 * np.eye(dimension)
    covariance = root @ root.T
    errors = rng.standard_normal((trials, runs, dimension)) @ np.linalg.cholesky(covariance).T
    average = nees(errors, np.broadcast_to(covariance, (trials, runs, dimension, dimension))).mean(axis=1)
    low, high = average_nees_band(runs, dimension)
    inside, above = np.mean((average >= low) & (average <= high)), np.mean(average > high)
    for fraction, expected in ((inside, 0.95), (above, 0.025)):
        assert abs(fraction - expected) < 4.0 * math.sqrt(expected * (1.0 - expected) / trials)
    assert average.mean() == pytest.approx(dimension, rel=0.01)


def test_nees_is_the_squared_error_in_standard_deviations_and_bad_inputs_are_named():
    errors = np.array(((0.2, -0.1, 0.0), (0.0, 0.0, 3.0)))
    sd = np.array((0.1, 0.5, 2.0))
    covariances = np.broadcast_to(np.diag(sd**2), (2, 3, 3))
    np.testing.assert_allclose(nees(errors, covariances), ((errors / sd) ** 2).sum(axis=1))
    with pytest.raises(ValueError, match=r"shape \(3, 3\) do not match errors of shape \(2, 3\)"):
        nees(errors, np.eye(3))
    with pytest.raises(ValueError, match="runs=0 must be an integer >= 1"):
        average_nees_band(0, 3)
    with pytest.raises(ValueError, match="probability=1.5"):
        average_nees_band(20, 3, 1.5)
    with pytest.raises(ValueError, match=r"amplitude=\[0.8\].*4 numbers"):
        weave([0.8], [0.2, 0.2, 0.2, 0.2], [0], 50)


def test_the_nees_part_writes_a_row_per_vehicle_flight_and_filter(tmp_path: Path, capsys):
    """``quad-wrench compare estimators --only nees`` on two runs of short flights; an estimator without
    a covariance is refused by name."""
    flights = {
        "hover": {"agent": "hold", "env": {"episode_seconds": 1.0, "fan": {"enabled": False}}},
        "manoeuvre": {
            "weave": {"amplitude": [0.8, 0.8, 0.8, 0.5], "frequency": [0.2, 0.25, 0.3, 0.15]},
            "env": {"episode_seconds": 1.0, "fan": {"enabled": False}},
        },
    }
    nees_config = {"estimators": ["ukf", "ekf"], "vehicles": ["ardrone2"], "first_seed": 3, "runs": 2}
    config = {
        "env_id": "QuadWrench/FanTracking-v1",
        "seeds": [0],
        "output": str(tmp_path / "out"),
        "nees": {**nees_config, "settle": 0.5, "flights": flights},
    }
    path = tmp_path / "nees.yaml"
    path.write_text(yaml.safe_dump(config))
    assert main(["compare", "estimators", "--only", "nees", "--config", str(path)]) == 0
    table = (tmp_path / "out" / "table.md").read_text()
    rows = [line for line in table.splitlines() if line.startswith("| ardrone2 |")]
    assert len(rows) == 4 and "seeds 3-4" in table
    assert all(f"| {average_nees_band(2, 3)[0]:.2f}-" in row for row in rows)
    capsys.readouterr()
    config["nees"]["estimators"] = ["observer"]
    path.write_text(yaml.safe_dump(config))
    with pytest.raises(ValueError, match=r"\['observer'\] carry no covariance"):
        main(["compare", "estimators", "--only", "nees", "--config", str(path)])
