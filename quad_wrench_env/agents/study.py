"""A study: arms of training runs (the same task trained with and without the wrench, with and without
memory, with each estimator), several training seeds each, all evaluated on the same held-out seeds and
cases beside the classical controllers, in one table with the spread across training seeds.

A :class:`StudyConfig` names a base training config, the ``arms`` (each a set of dotted overrides of it,
e.g. ``{env.observe_wrench: false, env.history: 8}``), the training ``seeds`` and a comparison config
(as ``quad-wrench compare agents`` takes: env id, env, held-out seeds, classical agents, cases).
:func:`study` trains each (arm, seed) into ``<folder>/runs/<arm>-seed<k>/`` on Ray (a local Ray on this
machine's cores by default, one run per CPU, or the cluster at ``address``), skipping finished runs and
resuming interrupted ones from their last checkpoint, so the same command continues a study; then it
flies each run's kept model and each classical agent on every case (one agent per Ray task) and
writes ``results.md`` (mean ± sd across training seeds of each run's mean over the held-out seeds;
the classical controllers' over the seeds; and which arms differ by more than their spread),
``results.csv`` (every run, case and metric) and ``results.png``.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from quad_wrench_env.agents.evaluate import Evaluation, compare, table_columns
from quad_wrench_env.agents.sb3 import (
    TrainConfig,
    TrainingConfigError,
    check_training,
    latest_snapshot,
    train,
    train_config,
)
from quad_wrench_env.agents.sweep import ray_session
from quad_wrench_env.config import apply_overrides, build, check_numbers, load_yaml, set_keys


@dataclass
class StudyConfig:
    """One study (a YAML file; see ``configs/study_*.yaml``)."""

    base: str | dict[str, Any] = field(default_factory=dict)
    """The training config every arm starts from: a path (relative to the study file) or a mapping."""
    common: dict[str, Any] = field(default_factory=dict)
    """Dotted overrides of ``base`` for every arm (e.g. ``{total_steps: 1500000}``: the same budget of
    env steps for each run, fair where runs share a loaded machine, unlike ``max_minutes``)."""
    arms: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Arm label -> dotted overrides of ``base`` (``{}``: the base as it is), after ``common``. An
    ``init_from`` or ``teacher`` of ``"@<arm>"`` names that arm's run of the same training seed (trained
    first): e.g. the oracle arm's policy fine-tuned on another estimator, or distilled into a student."""
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    """Training seeds of every arm (the config's ``seed``: vehicle i of a run starts from seed + i)."""
    comparison: str | dict[str, Any] = field(default_factory=dict)
    """Where every run and the classical agents are scored: a ``compare agents`` config (``env_id``,
    ``env``, ``seeds`` never trained on, ``agents`` (the classical ones), ``cases``), a path (relative
    to the study file) or a mapping. Each run flies in the config's env with its :meth:`flying_env`."""
    cpus_per_run: float = 1.0
    """CPUs Ray reserves for each run (a run steps its env and its network in one process)."""
    learning_rates: list[float] = field(default_factory=list)
    """The learning-rate sweep, the same for every arm (empty: none). An arm that trains (``total_steps``
    above 0) is first trained with the first training seed at each rate (``<arm>-lr<rate>-seed<k>``);
    the rate whose kept model scores best on the run's own selection seeds (``best/evaluation.yaml``,
    never the comparison's) is the arm's: that run is its first seed's, and its other seeds train at it."""

    def __post_init__(self) -> None:
        if not isinstance(self.common, dict):
            raise ValueError(f"common={self.common!r} must be a mapping of dotted overrides")
        if not (isinstance(self.arms, dict) and self.arms):
            raise ValueError(f"arms={self.arms!r} must name at least one arm (label -> overrides)")
        seeds = self.seeds
        if not (
            isinstance(seeds, list)
            and seeds
            and all(_is_seed(s) for s in seeds)
            and len(set(seeds)) == len(seeds)
        ):
            raise ValueError(f"seeds={seeds!r} must be a non-empty list of distinct integers >= 0")
        check_numbers("study", self, ("cpus_per_run",))
        rates = self.learning_rates
        if not (
            isinstance(rates, list)
            and all(isinstance(r, float | int) and not isinstance(r, bool) and r > 0 for r in rates)
            and len(set(rates)) == len(rates)
        ):
            raise ValueError(f"learning_rates={rates!r} must be a list of distinct numbers > 0")
        for label in self.arms:
            for key, source in self.sources(label).items():
                if source not in self.arms or self.sources(source):
                    raise ValueError(
                        f"arms[{label!r}].{key}='@{source}': allowed: an arm of this study that starts "
                        f"from no other arm, one of {[a for a in self.arms if not self.sources(a)]}"
                    )
            if rates and LEARNING_RATE in {**self.common, **self.arms[label]}:
                raise ValueError(
                    f"arms[{label!r}] sets {LEARNING_RATE} beside learning_rates={rates}: "
                    "the sweep sets every arm's rate; drop one of the two"
                )
        slugs = [slug(label) for label in self.arms]
        if len(set(slugs)) != len(slugs):
            raise ValueError(f"arms {list(self.arms)}: two labels give the same folder name {slugs}")
        for label in self.arms:
            for seed in seeds:
                try:
                    run = self.run_config(label, seed)
                except ValueError as error:
                    raise ValueError(f"arms[{label!r}]: {error}") from None
                if run.env_processes > self.cpus_per_run:
                    raise ValueError(
                        f"arms[{label!r}]: env_processes={run.env_processes} is more than "
                        f"cpus_per_run={self.cpus_per_run}: runs side by side would share cores"
                    )
        comparison = self.comparison_values()
        for key in ("env_id", "seeds", "cases"):
            if key not in comparison:
                raise ValueError(f"comparison: missing key {key!r} (a compare-agents config)")
        used = {s + i for s in seeds for i in range(self._vehicles())}
        used |= {s for label in self.arms for s in self.run_config(label, seeds[0]).evaluation.seeds}
        overlap = sorted(set(comparison["seeds"]) & used)
        if overlap:
            raise ValueError(
                f"comparison seeds {overlap} were trained on or chose the kept models; "
                "score on seeds never used in training"
            )

    def sources(self, label: str) -> dict[str, str]:
        """The arms that arm ``label``'s ``init_from`` and ``teacher`` name (``"@<arm>"``), by key."""
        overrides = {**self.common, **self.arms[label]}
        return {
            key: overrides[key][1:]
            for key in SOURCE_KEYS
            if isinstance(overrides.get(key), str) and overrides[key].startswith("@")
        }

    def run_config(
        self, label: str, seed: int, folder: Path | None = None, rate: float | None = None
    ) -> TrainConfig:
        """The training config of arm ``label`` with training seed ``seed`` (and learning rate ``rate``
        where given); an arm it starts from or learns from is that arm's run of the same seed under the
        study's ``folder`` (:meth:`run_path`)."""
        overrides = {**self.common, **self.arms[label], "seed": seed}
        if rate is not None:
            overrides[LEARNING_RATE] = rate
        for key, source in self.sources(label).items():
            path = self.run_path(folder, source, seed) if folder else run_folder(Path("."), source, seed)
            overrides[key] = str(path)
        return train_config(self.base_values(), overrides)

    def swept(self, label: str) -> bool:
        """Whether arm ``label``'s learning rate comes from the sweep (it trains, and there is one)."""
        return bool(self.learning_rates) and self.run_config(label, self.seeds[0]).total_steps > 0

    def runs(self) -> list[tuple[str, int, float | None]]:
        """Every run of the study as (arm, seed, the sweep's rate or None), in the config's order."""
        runs: list[tuple[str, int, float | None]] = []
        for label in self.arms:
            if self.swept(label):
                runs += [(label, self.seeds[0], rate) for rate in self.learning_rates]
                runs += [(label, seed, None) for seed in self.seeds[1:]]
            else:
                runs += [(label, seed, None) for seed in self.seeds]
        return runs

    def sweep_scores(self, folder: Path, label: str) -> dict[float, float] | None:
        """Each rate's kept-model score of arm ``label``'s sweep (NaN where the run kept none: no
        evaluation beat the untrained policy's place); None until every sweep run is done."""
        paths = {rate: self.sweep_folder(folder, label, rate) for rate in self.learning_rates}
        if any(status(path) != "done" for path in paths.values()):
            return None
        return {rate: kept_score(path) for rate, path in paths.items()}

    def chosen_rate(self, folder: Path, label: str) -> float | None:
        """The sweep's best rate for arm ``label`` (the run config's ``evaluation.lower_is_better``; a
        score of NaN never wins); None until every sweep run is done."""
        scores = self.sweep_scores(folder, label)
        if scores is None:
            return None
        return best_of(scores, self.run_config(label, self.seeds[0]).evaluation.lower_is_better)

    def sweep_folder(self, folder: Path, label: str, rate: float) -> Path:
        return folder / "runs" / f"{slug(label)}-lr{rate:g}-seed{self.seeds[0]}"

    def run_path(self, folder: Path, label: str, seed: int) -> Path:
        """The run folder of arm ``label`` and training seed ``seed``: the sweep's chosen run for the
        first seed of a swept arm (an error before the sweep is done), else ``<arm>-seed<k>``."""
        if self.swept(label) and seed == self.seeds[0]:
            rate = self.chosen_rate(folder, label)
            if rate is None:
                raise FileNotFoundError(f"arm {label!r}: its learning-rate sweep in {folder} is not done")
            return self.sweep_folder(folder, label, rate)
        return run_folder(folder, label, seed)

    def job(self, folder: Path, label: str, seed: int, rate: float | None) -> tuple[Path, TrainConfig] | None:
        """Run (``label``, ``seed``, ``rate``)'s folder and training config, or None while it waits: on
        its arm's sweep (a later seed of a swept arm) or on an arm it starts from or learns from."""
        for source in self.sources(label).values():
            if self.swept(source) and seed == self.seeds[0] and self.chosen_rate(folder, source) is None:
                return None
            if status(self.run_path(folder, source, seed)) != "done":
                return None
        if rate is not None:
            return self.sweep_folder(folder, label, rate), self.run_config(label, seed, folder, rate)
        if self.swept(label):
            chosen = self.chosen_rate(folder, label)
            if chosen is None:
                return None
            return run_folder(folder, label, seed), self.run_config(label, seed, folder, chosen)
        return run_folder(folder, label, seed), self.run_config(label, seed, folder)

    def flying_env(self, label: str, seed: int) -> dict[str, Any]:
        """The env settings a run of arm ``label`` brings to the comparison: its training env's
        estimator and its settings (:data:`ESTIMATOR_KEYS`: what it was trained to read) and the arm's
        own ``env`` overrides (and ``common``'s);
        the settings that give its observations and actions their meaning follow the policy anyway
        (:func:`quad_wrench_env.agents.evaluate.flying_settings`). The base's world (scenario draws,
        curricula such as a drawn start gap, a disturbance's heading spread) stays behind: every agent
        meets the comparison's episodes."""
        trained = self.run_config(label, seed).env
        own = set_keys({}, {**self.common, **self.arms[label]}).get("env", {})
        return {**{key: trained[key] for key in ESTIMATOR_KEYS if key in trained}, **own}

    def base_values(self) -> dict[str, Any]:
        return load_yaml(self.base) if isinstance(self.base, str) else dict(self.base)

    def comparison_values(self) -> dict[str, Any]:
        return load_yaml(self.comparison) if isinstance(self.comparison, str) else dict(self.comparison)

    def _vehicles(self) -> int:
        return max(self.run_config(label, self.seeds[0]).num_envs for label in self.arms)


LEARNING_RATE = "hyperparameters.learning_rate"
"""The training key the study's learning-rate sweep sets."""

SOURCE_KEYS = ("init_from", "teacher")
"""Training keys that may name another arm's run (``"@<arm>"``)."""

ESTIMATOR_KEYS = ("estimator", "estimator_params", "fan_walks")
"""The training env's settings a study's run brings to the comparison whatever its arm: the estimator
it was trained to read and its settings (FanTracking's ``fan_walks`` sizes its walks). A base that leaves
one to the task's default flies the comparison's."""


def kept_score(run: Path) -> float:
    """The selection score of run ``run``'s kept model (``best/evaluation.yaml``); NaN where it kept none
    (no evaluation beat the untrained policy's place)."""
    kept = run / "best" / "evaluation.yaml"
    return float(load_yaml(kept)["value"]) if kept.is_file() else math.nan


def best_of(scores: dict[Any, float], lower_is_better: bool) -> Any:
    """The key of the best of ``scores`` (a NaN never wins, unless every score is one: the first key)."""
    sign = 1.0 if lower_is_better else -1.0
    return min(scores, key=lambda key: sign * scores[key] if math.isfinite(scores[key]) else math.inf)


def _is_seed(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def slug(label: str) -> str:
    """A folder name for an arm label."""
    return re.sub(r"[^a-z0-9]+", "-", label.lower()).strip("-") or "arm"


def load_study_config(path: str | Path, overrides: list[str] | None = None) -> StudyConfig:
    """The :class:`StudyConfig` of the YAML file ``path`` with ``--set``-style ``key=value`` overrides;
    relative ``base`` and ``comparison`` paths are read from the file's folder."""
    values = apply_overrides(load_yaml(path), overrides or [])
    for key in ("base", "comparison"):
        if isinstance(values.get(key), str):
            values[key] = str(Path(path).resolve().parent / values[key])
    return build(StudyConfig, values)


def run_folder(folder: Path, label: str, seed: int) -> Path:
    return folder / "runs" / f"{slug(label)}-seed{seed}"


def status(run: Path) -> str:
    """``done`` (a final model), ``resume`` (a checkpoint to continue from) or ``new``."""
    if (run / "final" / "model.zip").is_file():
        return "done"
    try:
        latest_snapshot(run)
    except FileNotFoundError:
        return "new"
    return "resume"


def _train_run(values: dict[str, Any], folder: str, resume: bool) -> str:
    """One run (a Ray task): the training config ``values`` into ``folder``."""
    import shutil

    run = Path(folder)
    if not resume and run.exists():  # started but never checkpointed: start again
        shutil.rmtree(run)
    train(build(TrainConfig, values), run, resume=resume, progress=False)
    return folder


def train_all(config: StudyConfig, folder: Path, address: str | None = None) -> list[str]:
    """Every run not finished yet, on Ray, each as soon as what it waits on is done (its arm's
    learning-rate sweep, the arm it starts from or learns from: :meth:`StudyConfig.job`) and a run's
    CPUs are free, the longest first (:func:`_priority`); returns a line per run trained."""
    import ray

    lines: list[str] = []
    waiting = [run for run in config.runs() if status(_folder_of(config, folder, *run)) != "done"]
    if not waiting:
        return lines
    with ray_session(address):
        task = ray.remote(num_cpus=config.cpus_per_run)(_train_run)
        slots = max(1, int(ray.cluster_resources().get("CPU", 1.0) // config.cpus_per_run))
        running: dict[Any, tuple[str, int, float | None]] = {}
        while waiting or running:
            ready = [(run, job) for run in waiting if (job := config.job(folder, *run)) is not None]
            ready.sort(key=lambda item: _priority(config, item[0][0]))
            for run, (path, values) in ready[: slots - len(running)]:
                waiting.remove(run)
                resume = status(path) == "resume"
                running[task.remote(dataclasses.asdict(values), str(path), resume)] = run
            done, _ = ray.wait(list(running))
            label, seed, rate = running.pop(done[0])
            ray.get(done[0])
            lines.append(f"trained {label}, seed {seed}" + (f", learning rate {rate:g}" if rate else ""))
    return lines


SLOW_LEARNERS = ("recurrent_ppo", "dagger")
"""Algorithms whose runs take several times a PPO run's wall time per env step: started first."""


def _priority(config: StudyConfig, label: str) -> tuple[int, int]:
    """Which ready run starts first (lowest): a slow learner's, then an arm another arm waits on."""
    slow = config.run_config(label, config.seeds[0]).algorithm in SLOW_LEARNERS
    awaited = any(label in config.sources(other).values() for other in config.arms)
    return (0 if slow else 1, 0 if awaited else 1)


def _folder_of(config: StudyConfig, folder: Path, label: str, seed: int, rate: float | None) -> Path:
    return config.sweep_folder(folder, label, rate) if rate is not None else run_folder(folder, label, seed)


def _compare_one(comparison: dict[str, Any], label: str) -> dict[tuple[str, str], Evaluation]:
    """One agent of ``comparison`` on every case (a Ray task of :func:`evaluate_all`), without the
    episodes' traces, which the summary does not read."""
    results = compare({**comparison, "agents": {label: comparison["agents"][label]}})
    return {key: dataclasses.replace(ev, episodes=[]) for key, ev in results.items()}


def evaluate_all(
    config: StudyConfig, folder: Path, address: str | None = None
) -> dict[tuple[str, str], Evaluation]:
    """Each run's kept model (label ``<arm> seed <k>``, with its training env) and each classical agent
    of the comparison on every case (:func:`quad_wrench_env.agents.evaluate.compare`), one agent per Ray
    task with ``cpus_per_run`` CPUs (each episode is seeded, so the numbers do not depend on how the
    agents are spread); the results in the config's order: the classical agents, then the runs."""
    import ray

    comparison = config.comparison_values()
    agents = dict(comparison.get("agents", {}))
    for label in config.arms:
        for seed in config.seeds:
            agents[f"{label} seed {seed}"] = {
                "agent": str(config.run_path(folder, label, seed)),
                "env": config.flying_env(label, seed),
            }
    comparison = {**comparison, "agents": agents}
    with ray_session(address):
        task = ray.remote(num_cpus=config.cpus_per_run)(_compare_one)
        shared = ray.put(comparison)
        parts = ray.get([task.remote(shared, label) for label in agents])
    return {key: value for part in parts for key, value in part.items()}


def summary(config: StudyConfig, results: dict[tuple[str, str], Evaluation]) -> list[dict[str, Any]]:
    """One row per (arm or classical agent, case, metric): the mean and the spread (across training
    seeds of each run's mean over the held-out seeds; for a classical agent, over the seeds) and
    ``values``, what they summarise (each run's mean, in the order of ``seeds``; each held-out seed's
    value), joined by ``;``."""
    comparison = config.comparison_values()
    metrics = [key for key, _, _ in table_columns(comparison["env_id"])]
    rows = []
    for case in comparison["cases"]:
        for label in list(comparison.get("agents", {})) + list(config.arms):
            for metric in metrics:
                if label in config.arms:
                    values = [results[f"{label} seed {s}", case].mean[metric] for s in config.seeds]
                    kind = "arm"
                else:
                    values = [m[metric] for m in results[label, case].per_seed]
                    kind = "classical"
                values = np.array(values, dtype=float)
                rows.append(
                    {
                        "case": case,
                        "agent": label,
                        "kind": kind,
                        "metric": metric,
                        "mean": float(np.mean(values)),
                        "sd": float(np.std(values)),
                        "n": len(values),
                        "values": ";".join(f"{v:.6g}" for v in values),
                    }
                )
    return rows


def differences(rows: list[dict[str, Any]], metric: str) -> list[str]:
    """For ``metric``, the pairs of arms (and arm versus classical agent) per case whose means differ by
    more than their spreads together (``|a - b| > sd_a + sd_b``), the lower first."""
    lines = []
    for case in dict.fromkeys(r["case"] for r in rows):
        entries = [
            r for r in rows if r["case"] == case and r["metric"] == metric and math.isfinite(r["mean"])
        ]
        for i, a in enumerate(entries):
            for b in entries[i + 1 :]:
                if "arm" not in (a["kind"], b["kind"]):
                    continue
                low, high = sorted((a, b), key=lambda r: r["mean"])
                if high["mean"] - low["mean"] > low["sd"] + high["sd"]:
                    lines.append(
                        f"- {case}: {low['agent']} {low['mean']:.4g} ± {low['sd']:.2g} < {high['agent']} "
                        f"{high['mean']:.4g} ± {high['sd']:.2g}"
                    )
    return lines


def study(config: StudyConfig, folder: str | Path, address: str | None = None) -> list[dict[str, Any]]:
    """Train what is not trained yet, evaluate everything, write ``results.csv`` and ``results.md``;
    returns the summary rows (:func:`summary`), which :func:`figure` draws."""
    folder = Path(folder).resolve()
    for label in config.arms:  # env settings and hyperparameters, before any run starts
        try:
            run = config.run_config(label, config.seeds[0])
            check_training(run, folder / "runs" / "not-a-run", sources=not config.sources(label))
        except TrainingConfigError as error:
            raise TrainingConfigError(f"arms[{label!r}]: {error}") from None
    (folder / "runs").mkdir(parents=True, exist_ok=True)
    for line in train_all(config, folder, address):
        print(line, flush=True)
    rows = summary(config, evaluate_all(config, folder, address))
    write_results(config, folder, rows)
    return rows


def write_results(config: StudyConfig, folder: Path, rows: list[dict[str, Any]]) -> None:
    """``results.csv`` (every row) and ``results.md`` (the table and the differences)."""
    with (folder / "results.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    comparison = config.comparison_values()
    columns = table_columns(comparison["env_id"])
    header = ["agent", "case", *[title for _, title, _ in columns]]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for case in comparison["cases"]:
        for agent in dict.fromkeys(r["agent"] for r in rows):
            cells = []
            for key, _, fmt in columns:
                (row,) = [r for r in rows if r["case"] == case and r["agent"] == agent and r["metric"] == key]
                cells.append(
                    f"{fmt.format(row['mean'])} ± {fmt.format(row['sd'])}"
                    if math.isfinite(row["mean"])
                    else "n/a"
                )
            lines.append(f"| {agent} | {case} | " + " | ".join(cells) + " |")
    primary = columns[0][0]
    text = [
        f"# Study of {comparison['env_id']}: {len(config.arms)} arms x training seeds {config.seeds}",
        "",
        f"Arms (overrides of the base training config): {config.arms}; held-out seeds "
        f"{comparison['seeds']}. An arm's cell: mean ± sd across training seeds of each run's mean over "
        "the held-out seeds; a classical agent's: mean ± sd over the seeds.",
        "",
        *lines,
        "",
        f"Differences larger than the spreads together ({primary}):",
        "",
        *(differences(rows, primary) or ["- none"]),
        "",
        "Training (each run's last row of its curve.csv; its config.yaml beside it in runs/): env steps, "
        "wall time and env steps per second of wall time, mean over the arm's runs (the sweep's too)"
        + (
            "; the learning rate each arm's sweep chose, with the kept models' scores"
            if config.learning_rates
            else ""
        )
        + ":",
        "",
        *training_table(config, folder),
    ]
    (folder / "results.md").write_text("\n".join(text) + "\n")


def training_table(config: StudyConfig, folder: Path) -> list[str]:
    """A line per arm: its runs' env steps, wall minutes and env steps per second (from each run's
    ``curve.csv``), and its sweep's scores per rate with the one chosen."""
    lines = ["| arm | learning rate | env steps | wall time [min] | env steps/s |", "|---|---|---|---|---|"]
    for label in config.arms:
        done = []  # (steps, wall seconds) of each run: the last row of its curve
        for arm, seed, rate in config.runs():
            if arm == label:
                with (_folder_of(config, folder, arm, seed, rate) / "curve.csv").open() as handle:
                    last = list(csv.DictReader(handle))[-1]
                done.append((int(last["steps"]), float(last["wall_seconds"])))
        steps, seconds = np.array(done, dtype=float).T
        run = config.run_config(label, config.seeds[0])
        if config.swept(label):
            scores = config.sweep_scores(folder, label) or {}
            chosen = f" → {config.chosen_rate(folder, label):g}"
            rate = ", ".join(f"{r:g}: {v:.4g}" for r, v in scores.items()) + chosen
        else:
            rate = (
                f"{run.hyperparameters.get('learning_rate', '-')}" if run.total_steps else "- (not trained)"
            )
        speed = f"{np.mean(steps / seconds):,.0f}" if steps.min() > 0 else "-"
        lines.append(
            f"| {label} | {rate} | {steps.min():,.0f}-{steps.max():,.0f} | "
            f"{seconds.min() / 60:.1f}-{seconds.max() / 60:.1f} | {speed} |"
        )
    return lines


def figure(rows: list[dict[str, Any]], env_id: str) -> Any:
    """Bars of the task's first metric per case and agent, with the spreads of the table."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metric, title, _ = table_columns(env_id)[0]
    chosen = [r for r in rows if r["metric"] == metric]
    agents = list(dict.fromkeys(r["agent"] for r in chosen))
    cases = list(dict.fromkeys(r["case"] for r in chosen))
    fig, ax = plt.subplots(figsize=(1.6 * len(cases) + 3, 4.5))
    width = 0.8 / len(agents)
    palette = plt.get_cmap("tab10" if len(agents) <= 10 else "tab20").colors
    for k, agent in enumerate(agents):
        picked = [next(r for r in chosen if r["agent"] == agent and r["case"] == c) for c in cases]
        ax.bar(
            np.arange(len(cases)) + k * width,
            [r["mean"] for r in picked],
            width,
            yerr=[r["sd"] for r in picked],
            label=agent,
            color=palette[k % len(palette)],
            capsize=2,
        )
    ax.set_xticks(np.arange(len(cases)) + 0.4 - width / 2, cases, rotation=20, ha="right")
    ax.set_xlabel("case")
    ax.set_ylabel(title)
    ax.set_title("arms: across training seeds; classical: across held-out seeds", fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))  # beside the bars, never on them
    return fig
