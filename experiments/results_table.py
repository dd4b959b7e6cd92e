"""
Summarise the JSON lines of ``experiments/uav_learning.py`` runs: one table row per label (mean ± std over seeds of
each seed's 20-episode means, and the worst-decile team return), and a figure of the learning curves (coverage and
energy efficiency against timesteps, one line per seed).

    python experiments/results_table.py runs/results/*.jsonl --figure docs/figures/learning_curves_v1.png

A run's label is its file name up to the last ``_s<seed>`` (``alpha05_s0.jsonl`` -> ``alpha05``).
"""

import argparse
import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

COLUMNS = ("coverage", "fairness", "energy", "energy_efficiency", "return_worst_decile")
HEADER = "| run | seeds | c_T | f_T | ē_T | η_T | worst-decile team return | train min/seed |"


def label_of(path: Path) -> str:
    return re.sub(r"_s\d+$", "", path.stem)


def load(paths: list[Path]) -> tuple[dict[str, list[dict]], dict[str, dict[int, list[dict]]]]:
    finals: dict[str, list[dict]] = defaultdict(list)
    curves: dict[str, dict[int, list[dict]]] = defaultdict(lambda: defaultdict(list))
    for path in paths:
        for line in path.read_text().splitlines():
            record = json.loads(line)
            if record["kind"] == "final":
                finals[label_of(path)].append(record)
            else:
                curves[label_of(path)][record["seed"]].append(record)
    return finals, curves


def table(finals: dict[str, list[dict]]) -> str:
    rows = [HEADER, "|" + "---|" * 8]
    for label, records in finals.items():
        cells = []
        for key in COLUMNS:
            values = np.array([r[key] for r in records])
            cells.append(f"{values.mean():.3f} ± {values.std():.3f}")
        minutes = np.mean([r["train_seconds"] for r in records]) / 60
        seeds = ",".join(str(r["seed"]) for r in sorted(records, key=lambda r: r["seed"]))
        rows.append(f"| {label} | {seeds} | " + " | ".join(cells) + f" | {minutes:.1f} |")
    return "\n".join(rows)


def figure(curves: dict[str, dict[int, list[dict]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for colour, (label, seeds) in zip(colours, curves.items(), strict=False):
        for i, (_seed, records) in enumerate(sorted(seeds.items())):
            steps = [r["timesteps"] for r in records]
            for axis, key in zip(axes, ("coverage", "energy_efficiency"), strict=True):
                axis.plot(steps, [r[key] for r in records], color=colour, alpha=0.8, label=label if i == 0 else None)
    for axis, title in zip(axes, ("coverage c_T", "energy efficiency η_T"), strict=True):
        axis.set_xlabel("timesteps")
        axis.set_title(f"{title} (5 random-start episodes per point)")
        axis.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("files", nargs="+", type=Path)
    parser.add_argument("--figure", type=Path, help="write the learning curves here")
    args = parser.parse_args()
    finals, curves = load(args.files)
    print(table(finals))
    if args.figure:
        figure(curves, args.figure)


if __name__ == "__main__":
    main()
