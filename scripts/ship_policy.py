"""Ship a study's run as a named policy: the arm's best training seed on its selection seeds.

    python scripts/ship_policy.py STUDY_CONFIG STUDY_FOLDER ARM NAME

Copies the run's ``config.yaml`` (``init_from`` and ``teacher`` as paths relative to the study folder,
never this machine's), ``commit.txt``, ``curve.csv`` and its kept model (``best/``, else ``final/``) into
``quad_wrench_env/agents/policies/NAME/`` and writes ``metrics.md``: which run it is, its budget, its
selection score and its held-out numbers in the study (``results.csv``: the run's mean over the held-out
seeds per case and metric, beside the arm's and the study's classical agents' on the same seeds). The
policy then flies by name with the env settings it was trained with.
"""

from __future__ import annotations

import argparse
import csv
import shutil
from pathlib import Path

import yaml

from quad_wrench_env.agents.study import SOURCE_KEYS, best_of, kept_score, load_study_config
from quad_wrench_env.config import load_yaml

POLICIES = Path(__file__).resolve().parents[1] / "quad_wrench_env" / "agents" / "policies"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("config")
    parser.add_argument("folder")
    parser.add_argument("arm")
    parser.add_argument("name")
    args = parser.parse_args()
    config, folder = load_study_config(args.config), Path(args.folder).resolve()
    if args.arm not in config.arms:
        parser.error(f"arm {args.arm!r} is not in the study; allowed: {list(config.arms)}")
    evaluation = config.run_config(args.arm, config.seeds[0]).evaluation
    scores = {seed: kept_score(config.run_path(folder, args.arm, seed)) for seed in config.seeds}
    seed = best_of(scores, evaluation.lower_is_better)
    run = config.run_path(folder, args.arm, seed)
    target = POLICIES / args.name
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    settings = load_yaml(run / "config.yaml")
    for key in SOURCE_KEYS:
        if settings.get(key):
            settings[key] = str(Path(settings[key]).resolve().relative_to(folder))
    (target / "config.yaml").write_text(yaml.safe_dump(settings, sort_keys=False))
    for name in ("commit.txt", "curve.csv"):
        shutil.copy(run / name, target / name)
    kept = "best" if (run / "best" / "model.zip").is_file() else "final"
    (target / kept).mkdir()
    for name in ("model.zip", "scaling.npz", "evaluation.yaml"):
        if (run / kept / name).is_file():
            shutil.copy(run / kept / name, target / kept / name)
    with (run / "curve.csv").open() as handle:
        last = list(csv.DictReader(handle))[-1]
    with (folder / "results.csv").open() as handle:
        results = list(csv.DictReader(handle))
    rows = [r for r in results if r["agent"] == args.arm]
    classical = {(r["case"], r["metric"], r["agent"]): r for r in results if r["kind"] == "classical"}
    baselines = list(dict.fromkeys(agent for _, _, agent in classical))
    position = config.seeds.index(seed)
    lines = [
        f"# {args.name}",
        "",
        f'The run of `quad-wrench study {args.config} --folder <folder>` in the arm "{args.arm}" '
        f"({config.arms[args.arm]}) with training seed {seed} (`{run.relative_to(folder)}`; config.yaml here "
        "is the config it ran with, commit.txt the code): "
        f"{int(last['steps']):,} env steps in {float(last['wall_seconds']):.0f} s of wall time. Of the arm's "
        f"training seeds {config.seeds} it is the one whose kept model (`{kept}/`) scores best on its "
        f"selection seeds {evaluation.seeds} by `{evaluation.metric}`: "
        + ", ".join(f"seed {s}: {v:.4g}" for s, v in scores.items())
        + f'. By name it flies with the env settings it was trained with (`make_agent("{args.name}")`).',
        "",
        "Its mean over the study's held-out seeds per case beside the arm's (mean ± sd across training "
        "seeds) and the study's classical agents' on the same seeds (mean ± sd over the seeds):",
        "",
        "| case | metric | this run | the arm, mean ± sd across training seeds | "
        + " | ".join(baselines)
        + " |",
        "|---|---|---|---|" + "---|" * len(baselines),
    ]
    for r in rows:
        value = float(r["values"].split(";")[position])
        beside = [classical[(r["case"], r["metric"], agent)] for agent in baselines]
        lines.append(
            f"| {r['case']} | {r['metric']} | {value:.4g} | {float(r['mean']):.4g} ± {float(r['sd']):.2g} | "
            + " | ".join(f"{float(b['mean']):.4g} ± {float(b['sd']):.2g}" for b in beside)
            + " |"
        )
    (target / "metrics.md").write_text("\n".join(lines) + "\n")
    print(f"shipped {args.arm!r} seed {seed} as {target}")


if __name__ == "__main__":
    main()
