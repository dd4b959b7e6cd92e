"""
The table of ``experiments/tmc_sweep.sh``: for each N, the baselines measured here (mean ± std over episodes), the
trained MADDPG runs (mean ± std over seeds of each seed's episode means, and the training minutes per seed) and the
paper's eta_T at that N.

    python experiments/tmc_table.py experiments/results/2026-12-04-tmc experiments/results/2026-12-05-tmc \
        experiments/results/2026-12-06-tmc/sweep --figure docs/figures/tmc_eta_vs_n.png

Reads ``<out>/baselines/n<N>/results.csv``, ``<out>/eval/[<tag>_]n<N>_s<seed>/results.csv`` (the ``evaluate``
command's) and ``<out>/train_[<tag>_]n<N>_s<seed>.seconds`` of every folder given (the runs of one sweep may lie in
several). Runs with a tag (``TAG`` of tmc_sweep.sh, e.g. ``attn`` for the attention critic) are rows and lines of their
own, named after it; so are the best-of-checkpoints rows of ``<out>/best_of_k/[<tag>_]n<N>_s<seed>/results.csv``
(``python -m sb3_maddpg select-checkpoint``'s folders): "<method> <tag> best of K".
"""

import argparse
import csv
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

METRICS = ("coverage", "fairness", "energy", "energy_efficiency")
# eta_T of Liu et al., IEEE TMC 19(6), 2020, against N (R' 3): its figure data (docs/results.md, "The published setting")
PAPER_ETA = {
    "paper MADDPG-style": {3: 0.835, 4: 1.006, 5: 1.171, 6: 1.435, 7: 1.472, 8: 1.542},
    "paper DRL-EC3": {3: 0.655, 4: 0.893, 5: 1.134, 6: 1.232, 7: 1.415, 8: 1.430},
    "paper random": {3: 0.503, 4: 0.741, 5: 0.937, 6: 1.063, 7: 1.222, 8: 1.326},
}


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path) as file:
        return list(csv.DictReader(file))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("out", type=Path, nargs="+", help="the sweep's output folders (OUT of tmc_sweep.sh)")
    parser.add_argument("--figure", type=Path, help="also draw eta_T against N (the paper's lines and ours) here")
    args = parser.parse_args()
    etas: dict[str, dict[int, tuple[float, float]]] = defaultdict(dict)  # method -> N -> (mean, std)

    lines = ["| N | method | episodes | c_T | f_T | ē_T | η_T | train min/seed |", "|---|---|---|---|---|---|---|---|"]
    baselines = [folder for out in args.out for folder in (out / "baselines").glob("n*")]
    for folder in sorted(baselines, key=lambda p: int(p.name[1:])):
        for row in read_rows(folder / "results.csv"):
            cells = [f"{float(row[f'{key}_mean']):.3f} ± {float(row[f'{key}_std']):.3f}" for key in METRICS]
            lines.append(f"| {folder.name[1:]} | {row['method']} | {row['episodes']} | " + " | ".join(cells) + " | |")
            eta = (float(row["energy_efficiency_mean"]), float(row["energy_efficiency_std"]))
            etas[f"{row['method']} (here)"][int(folder.name[1:])] = eta

    # Trained runs: one seed's value is its mean over the episodes; the row is mean ± std over seeds.
    # The best-of-checkpoints rows (select-checkpoint's folders) are rows of their own: "<method> <tag> best of K".
    trained: dict[tuple[str, int], list[dict[str, str]]] = defaultdict(list)  # (method, N) -> one row per seed
    seconds: dict[tuple[str, int], list[float]] = defaultdict(list)
    for kind in ("eval", "best_of_k"):
        for folder in [folder for out in args.out for folder in (out / kind).glob("*n*_s*")]:
            match = re.fullmatch(r"(?:(\w+)_)?n(\d+)_s(\d+)", folder.name)
            if not (match and (folder / "results.csv").is_file()):
                continue
            tag, n = match.group(1) or "", int(match.group(2))
            if kind == "eval":
                method = f"maddpg {tag}".strip()
                trained[method, n] += [r for r in read_rows(folder / "results.csv") if r["method"] != "random"]
                timing = folder.parent.parent / f"train_{folder.name}.seconds"
                if timing.is_file():
                    seconds[method, n].append(float(timing.read_text()))
            else:
                best = [r for r in read_rows(folder / "results.csv") if r["method"].startswith("best of")]
                trained[f"maddpg {tag} best of K".replace("  ", " "), n] += best
    for method, n in sorted(trained, key=lambda key: (key[1], key[0])):
        rows, timings = trained[method, n], seconds[method, n]
        cells = []
        for key in METRICS:
            values = np.array([float(r[f"{key}_mean"]) for r in rows])
            cells.append(f"{values.mean():.3f} ± {values.std():.3f}")
        minutes = f"{np.mean(timings) / 60:.1f}" if timings else ""
        seed_etas = np.array([float(r["energy_efficiency_mean"]) for r in rows])
        # one line for each trained method whatever the seeds per N (the table gives them)
        etas[f"{method} (here, mean ± std over seeds)"][n] = (float(seed_etas.mean()), float(seed_etas.std()))
        by_seed = ", ".join(f"{eta:.3f}" for eta in seed_etas)
        label = f"| {n} | {method} ({len(rows)} seeds: {by_seed}) | {rows[0]['episodes']} each | "
        lines.append(label + " | ".join(cells) + f" | {minutes} |")
    print("\n".join(lines))

    ns = sorted(next(iter(PAPER_ETA.values())))
    print()
    print("| paper (η_T) | " + " | ".join(f"N {n}" for n in ns) + " |")
    print("|---|" + "---|" * len(ns))
    for method, values in PAPER_ETA.items():
        print(f"| {method} | " + " | ".join(f"{values[n]:.3f}" for n in ns) + " |")
    if args.figure:
        draw_figure(args.figure, etas)


def draw_figure(path: Path, etas: dict[str, dict[int, tuple[float, float]]]) -> None:
    """eta_T against N: the paper's methods dashed, ours solid (mean ± std), the limit 1 / 0.5 = 2 dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6.4, 4.2))
    for method, values in PAPER_ETA.items():
        ns = sorted(values)
        axes.plot(ns, [values[n] for n in ns], linestyle="--", marker="s", markersize=4, label=method)
    for method, values in sorted(etas.items()):
        ns = sorted(values)
        axes.errorbar(
            ns, [values[n][0] for n in ns], yerr=[values[n][1] for n in ns], marker="o", markersize=4, capsize=3, label=method
        )
    axes.axhline(2.0, color="grey", linestyle=":", label="limit (c = f = 1, hovering)")
    axes.set_xlabel("number of UAVs N")
    axes.set_ylabel("energy efficiency η_T")
    axes.set_title("uav_coverage_tmc_v1 against Liu et al. (TMC 2020)")
    axes.legend(fontsize=7, loc="lower right")
    axes.grid(alpha=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(figure)
    print(f"figure: {path}")


if __name__ == "__main__":
    main()
