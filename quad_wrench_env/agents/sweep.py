"""Hyperparameter sweeps of training runs on Ray Tune: grid, random or Optuna search, on the local
machine or an existing Ray cluster (the optional extra: ``pip install "quad-wrench-env[tune]"``).

A :class:`SweepConfig` names a base training config (``configs/train_*.yaml``, or one inline) and a
search ``space`` over its dotted keys (``hyperparameters.learning_rate``, ``seed``,
``env.observe_wrench``, ...). :func:`sweep` runs each trial as an ordinary training run
(``quad_wrench_env.agents.sb3.train``) into ``<folder>/runs/<trial id>/``, scores it by the best evaluation
of its ``curve.csv`` under the base config's ``evaluation.metric``, and writes one table of all trials
(``results.csv``, ``results.md``) and the best trial's full training config (``best_config.yaml``,
which ``quad-wrench train`` takes as it is).
"""

from __future__ import annotations

import csv
import dataclasses
import logging
import math
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from quad_wrench_env.agents.sb3 import TrainConfig, train, train_config
from quad_wrench_env.config import apply_overrides, build, check_numbers, load_yaml

SEARCHES = ("grid", "random", "optuna")
DISTRIBUTIONS = ("choice", "uniform", "loguniform", "randint")
"""Specs every search takes; ``grid`` (every listed value) only ``search: grid``."""
SPECS = ("grid", *DISTRIBUTIONS)
INSTALL = 'sweeps need Ray Tune and Optuna: pip install "quad-wrench-env[tune]"'


@dataclass
class SweepConfig:
    """A sweep over training configs (one YAML file; see ``configs/sweep_*.yaml``)."""

    base: str | dict[str, Any] = field(default_factory=dict)
    """The training config swept: a path (relative paths from the sweep file's folder when loaded by
    :func:`load_sweep_config`) or the config itself ({}: ``TrainConfig``'s defaults)."""
    search: str = "grid"
    """``grid`` (Ray's variant generator: the product of the ``grid`` values, ``num_samples`` times,
    other specs drawn for each), ``random`` (``num_samples`` draws) or ``optuna`` (Optuna's TPE
    sampler, ``num_samples`` trials)."""
    space: dict[str, Any] = field(default_factory=dict)
    """Dotted training-config key -> one spec: ``{grid: [a, b]}``, ``{choice: [a, b]}``,
    ``{uniform: [lo, hi]}``, ``{loguniform: [lo, hi]}``, ``{randint: [lo, hi]}`` (hi excluded, as in
    Ray). The ``evaluation`` section is the yardstick of every trial and cannot be swept."""
    num_samples: int = 1
    max_concurrent_trials: int = 0
    """Trials run at once at most (0: as many as the cluster's CPUs allow)."""
    cpus_per_trial: float = 1.0
    """CPUs Ray reserves for each trial (one trial steps its env and its network in one process;
    ``threads`` of the base config sets the network's torch threads)."""
    seed: int = 0
    """Seeds the searcher (random draws, Optuna's sampler); the training seed is the base's ``seed``
    key, which the space may sweep."""

    def __post_init__(self) -> None:
        if self.search not in SEARCHES:
            raise ValueError(f"search={self.search!r}; allowed: {list(SEARCHES)}")
        for name, low in (("num_samples", 1), ("max_concurrent_trials", 0), ("seed", 0)):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= low):
                raise ValueError(f"{name}={value!r} must be an integer >= {low}")
        check_numbers("sweep", self, ("cpus_per_trial",))
        if not self.space:
            raise ValueError("space={} must name at least one training-config key to sweep")
        base = self.base_values()
        for key, spec in self.space.items():
            if key.split(".")[0] == "evaluation":
                raise ValueError(
                    f"space[{key!r}]: the evaluation section scores every trial alike; not swept"
                )
            for value in _candidates(key, spec, self.search):
                try:
                    train_config(base, {key: value})
                except ValueError as error:
                    raise ValueError(f"space[{key!r}]: {error}") from None

    def base_values(self) -> dict[str, Any]:
        """The base training config as a mapping (read from its file where ``base`` is a path)."""
        return load_yaml(self.base) if isinstance(self.base, str) else dict(self.base)


def _candidates(key: str, spec: Any, search: str) -> list[Any]:
    """Values that ``spec`` may give ``key`` (each listed one, or a range's ends), checked for form."""
    if not (isinstance(spec, Mapping) and len(spec) == 1 and next(iter(spec)) in SPECS):
        raise ValueError(f"space[{key!r}]={spec!r} must be a mapping of one of {list(SPECS)} to its values")
    kind, values = next(iter(spec.items()))
    if kind == "grid" and search != "grid":
        raise ValueError(f"space[{key!r}]: grid needs search: grid; search {search!r} takes {DISTRIBUTIONS}")
    if kind in ("grid", "choice"):
        if not (isinstance(values, list) and values):
            raise ValueError(f"space[{key!r}].{kind}={values!r} must be a non-empty list")
        return list(values)
    integer = kind == "randint"
    numbers_ok = isinstance(values, list) and len(values) == 2 and all(_is_number(v, integer) for v in values)
    if not (numbers_ok and values[0] < values[1] and (kind != "loguniform" or values[0] > 0)):
        what = "integers" if integer else "positive numbers" if kind == "loguniform" else "numbers"
        raise ValueError(f"space[{key!r}].{kind}={values!r} must be [low, high], {what} with low < high")
    return [values[0], values[1] - 1] if integer else [float(values[0]), float(values[1])]


def _is_number(value: Any, integer: bool) -> bool:
    if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)):
        return False
    return math.isfinite(value)


def load_sweep_config(path: str | Path, overrides: list[str] | None = None) -> SweepConfig:
    """The :class:`SweepConfig` of the YAML file ``path`` with ``--set``-style ``key=value``
    ``overrides`` (e.g. ``num_samples=32``, ``search=optuna``; dots reach into sections, so a dotted
    key of ``space`` is set in the file); a relative ``base`` path is read from the file's folder."""
    values = apply_overrides(load_yaml(path), overrides or [])
    if isinstance(values.get("base"), str):
        values["base"] = str(Path(path).resolve().parent / values["base"])
    return build(SweepConfig, values)


@dataclass
class SweepResult:
    """What a sweep found: one row per trial, best first, and the best trial's training config."""

    folder: Path
    metric: str
    rows: list[dict[str, Any]]
    """``trial``, each swept key, the metric, ``steps``, ``wall_seconds``, ``run`` (the trial's run
    folder) and ``error`` (empty unless the trial failed; its metric is then NaN)."""
    best: dict[str, Any]
    """The best row."""
    config: TrainConfig
    """The best trial's training config (also ``folder/best_config.yaml``)."""


def sweep(
    config: SweepConfig, folder: str | Path, address: str | None = None, progress: bool = True
) -> SweepResult:
    """Run ``config``'s trials on Ray Tune into the empty (or new) ``folder``: ``runs/<trial id>/``
    (each trial's run folder), ``ray/`` (Tune's own records), ``results.csv`` and ``results.md`` (all
    trials, best first) and ``best_config.yaml``. Ray is one already started in this process, else the
    cluster at ``address`` (whose nodes must have this package installed and see ``folder`` at the
    same path), else a local one on all of this machine's cores; ``progress``: Tune's status table."""
    try:
        from ray import tune
    except ImportError as error:
        raise ImportError(INSTALL) from error
    folder = Path(folder).resolve()
    if folder.exists() and any(folder.iterdir()):
        raise FileExistsError(f"sweep folder {str(folder)!r} is not empty; pass a new folder")
    base = config.base_values()
    evaluation = build(TrainConfig, base).evaluation
    mode = "min" if evaluation.lower_is_better else "max"
    # Trials keep the driver's working directory (Tune passes this variable on to its trial actors).
    os.environ["RAY_CHDIR_TO_TRIAL_DIR"] = "0"
    with ray_session(address):
        trainable = tune.with_parameters(
            _run_trial, base=base, runs=str(folder / "runs"), metric=evaluation.metric, mode=mode
        )
        tuner = tune.Tuner(
            tune.with_resources(trainable, {"cpu": config.cpus_per_trial}),
            param_space={key: _domain(spec) for key, spec in config.space.items()},
            tune_config=tune.TuneConfig(
                metric=evaluation.metric,
                mode=mode,
                search_alg=_searcher(config),
                num_samples=config.num_samples,
                max_concurrent_trials=config.max_concurrent_trials or None,
            ),
            run_config=tune.RunConfig(storage_path=str(folder), name="ray", verbose=None if progress else 0),
        )
        results = tuner.fit()
    rows = _rows(results, folder / "runs", list(config.space), evaluation.metric, mode)
    _write_tables(folder, rows)
    return _best(folder, rows, base, list(config.space), evaluation.metric)


@contextmanager
def ray_session(address: str | None) -> Iterator[None]:
    """Ray for the block: one already started in this process, else the cluster at ``address``, else a
    local one on all of this machine's cores (shut down after the block). No cluster at ``address``:
    ``ConnectionError`` naming it, before anything runs."""
    import ray

    started = not ray.is_initialized()
    if started:
        local = {} if address else {"num_cpus": os.cpu_count(), "include_dashboard": False}
        try:
            ray.init(address=address, log_to_driver=False, logging_level=logging.WARNING, **local)
        except ConnectionError as error:
            raise ConnectionError(f"address={address!r}: {str(error).splitlines()[0]}") from None
    try:
        yield
    finally:
        if started:
            ray.shutdown()


def _domain(spec: Mapping[str, Any]) -> Any:
    """The Ray Tune search-space domain of a spec (``{loguniform: [lo, hi]}`` -> ``tune.loguniform``)."""
    from ray import tune

    kind, values = next(iter(spec.items()))
    if kind == "grid":
        return tune.grid_search(values)
    return tune.choice(values) if kind == "choice" else getattr(tune, kind)(*values)


def _searcher(config: SweepConfig) -> Any:
    """Ray's variant generator (grid, random) or Optuna's TPE sampler, seeded by ``config.seed``."""
    if config.search == "optuna":
        from ray.tune.search.optuna import OptunaSearch

        return OptunaSearch(seed=config.seed)
    from ray.tune.search import BasicVariantGenerator

    return BasicVariantGenerator(random_state=config.seed)


def _run_trial(overrides: dict[str, Any], base: dict[str, Any], runs: str, metric: str, mode: str) -> None:
    """One trial: the base training config with the trial's ``overrides``, trained into
    ``runs/<trial id>``, reported to Tune by the best evaluation of its trained policy."""
    from ray import tune

    config = train_config(base, overrides)
    folder = train(config, Path(runs) / tune.get_context().get_trial_id(), progress=False)
    with (folder / "curve.csv").open() as handle:
        curve = list(csv.DictReader(handle))
    trained = [  # as train() keeps its best model: never the evaluation of the untrained policy
        float(r["metric"])
        for r in curve
        if int(r["steps"]) > config.num_envs and math.isfinite(float(r["metric"]))
    ]
    best = (min if mode == "min" else max)(trained, default=math.nan)
    tune.report({metric: best, "steps": int(curve[-1]["steps"])})


def _rows(results: Any, runs: Path, keys: list[str], metric: str, mode: str) -> list[dict[str, Any]]:
    """One row per trial of Tune's ``ResultGrid`` (run folders under ``runs``), best first, failed and
    unscored trials last."""
    rows = []
    for result in results:
        reported = result.metrics
        trial = reported["trial_id"]
        rows.append(
            {
                "trial": trial,
                **{key: result.config.get(key) for key in keys},
                metric: float(reported.get(metric, math.nan)),
                "steps": reported.get("steps", 0),
                "wall_seconds": round(float(reported.get("time_total_s", math.nan)), 1),
                "run": str(runs / trial),
                "error": str(result.error).strip().splitlines()[-1] if result.error else "",
            }
        )
    sign = 1.0 if mode == "min" else -1.0
    return sorted(rows, key=lambda r: sign * r[metric] if math.isfinite(r[metric]) else math.inf)


def _write_tables(folder: Path, rows: list[dict[str, Any]]) -> None:
    """``results.csv`` and ``results.md``: the same table."""
    columns = list(rows[0])
    with (folder / "results.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows(rows)
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_cell(row[c]) for c in columns) + " |" for row in rows]
    (folder / "results.md").write_text("\n".join(lines) + "\n")


def _cell(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value).replace("|", "\\|")


def _best(
    folder: Path, rows: list[dict[str, Any]], base: dict[str, Any], keys: list[str], metric: str
) -> SweepResult:
    """The sweep's result, with the best trial's config written to ``best_config.yaml``; an error if
    no trial scored."""
    best = rows[0]
    if not math.isfinite(best[metric]):
        raise RuntimeError(
            f"no trial of the sweep scored {metric}; see {folder / 'results.md'}: {best['error']}"
        )
    config = train_config(base, {key: best[key] for key in keys})
    header = f"# The best trial ({best['trial']}, {metric} {best[metric]:.4g}) of the sweep in {folder}\n"
    (folder / "best_config.yaml").write_text(
        header + yaml.safe_dump(dataclasses.asdict(config), sort_keys=False)
    )
    return SweepResult(folder, metric, rows, best, config)
