"""
The alpha sweep's table and figure: the final evaluations of ``run_results.sh`` runs (``<variant>_s<seed>.jsonl``,
the line of kind ``final``) or evaluation folders of ``python -m sb3_maddpg evaluate`` (``eval_<variant>_s<seed>``,
as ``hazard_finetune.sh`` writes them) read back from one folder, one row per variant with the
mean ± std over seeds of each seed's mean team return, worst-decile team return (the mean of its worst 10 % of
episodes), hazard events per episode, c_T, f_T and eta_T; then one line per seed; and a figure of the mean against the
worst decile, one point per variant and seed.

    python experiments/alpha_sweep_table.py runs/stsc --variants st_classic st_a1 st_a05 st_a025 st_a01 \
        --figure docs/figures/storm_alpha_sweep.png

A variant is the file name up to ``_s<seed>.jsonl``, or the folder name between ``eval_`` and ``_s<seed>``; its
label in the table is the variant name unless ``--labels`` gives one per variant.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
from pathlib import Path

#: (key in the summary row, column title, digits)
COLUMNS = (
    ("return_mean", "team return", 1),
    ("return_worst_decile", "worst-decile team return", 1),
    ("crashes_mean", "crashes (strikes) / episode", 2),
    ("link_failures_mean", "link failures / episode", 1),
    ("depletions_mean", "depletions / episode", 2),
    ("coverage_mean", "c_T", 3),
    ("fairness_mean", "f_T", 3),
    ("energy_efficiency_mean", "η_T", 3),
    ("zone_steps_mean", "zone steps / episode", 2),
    ("zone_losses_mean", "zone losses / episode", 2),
)


def read_rows(folder: Path, method: str = "maddpg") -> dict[str, dict[int, dict[str, float]]]:
    """
    The summary rows of the evaluations in ``folder``: variant -> seed -> row (keys as in ``evaluate``'s summary).

    :param folder: the folder holding ``<variant>_s<seed>.jsonl`` or ``eval_<variant>_s<seed>/results.json``
    :param method: the evaluated method's row (``evaluate`` writes the baselines' rows beside it)
    """
    rows: dict[str, dict[int, dict[str, float]]] = {}
    for log in sorted(folder.glob("*_s*.jsonl")):
        match = re.fullmatch(r"(.+)_s(\d+)\.jsonl", log.name)
        finals = [line for line in map(json.loads, log.read_text().splitlines()) if line.get("kind") == "final"]
        if match is None or not finals:
            continue
        # the final line holds the means under the metrics' own names, the worst decile under its summary name
        final = finals[-1]
        row = {f"{key}_mean": value for key, value in final.items() if isinstance(value, (int, float))}
        row["return_worst_decile"] = final["return_worst_decile"]
        rows.setdefault(match.group(1), {})[int(match.group(2))] = row
    for results in sorted(folder.glob("eval_*_s*/results.json")):
        match = re.fullmatch(r"eval_(.+)_s(\d+)", results.parent.name)
        if match is None:
            continue
        summary = {row["method"]: row for row in json.loads(results.read_text())["summary"]}
        if method in summary:
            rows.setdefault(match.group(1), {})[int(match.group(2))] = summary[method]
    return rows


def mean_std(values: list[float], digits: int) -> str:
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{statistics.mean(values):.{digits}f} ± {statistics.stdev(values):.{digits}f}"


def table(rows: dict[str, dict[int, dict[str, float]]], variants: list[str], labels: list[str]) -> str:
    """
    The markdown table: one row per variant, mean ± std over its seeds, then each seed's mean and worst decile. Columns
    that no evaluation reports (the UAV metrics on risky_reach_v0, its zone counts on the UAV tasks) are left out.
    """
    columns = [column for column in COLUMNS if any(column[0] in row for seeds in rows.values() for row in seeds.values())]
    head = ["variant", "seeds", *(title for _, title, _ in columns), "mean / worst decile by seed"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for variant, label in zip(variants, labels, strict=True):
        by_seed = rows.get(variant, {})
        if not by_seed:
            lines.append(f"| {label} | (none) |" + " |" * (len(head) - 2))
            continue
        seeds = sorted(by_seed)
        cells = [
            mean_std([by_seed[s][key] for s in seeds], digits) if all(key in by_seed[s] for s in seeds) else ""
            for key, _, digits in columns
        ]
        per_seed = ", ".join(f"{by_seed[s]['return_mean']:.1f} / {by_seed[s]['return_worst_decile']:.1f}" for s in seeds)
        lines.append(f"| {label} | {', '.join(map(str, seeds))} | " + " | ".join(cells) + f" | {per_seed} |")
    return "\n".join(lines)


def figure(
    rows: dict[str, dict[int, dict[str, float]]],
    variants: list[str],
    labels: list[str],
    path: Path,
    references: list[dict[str, float]] | None = None,
) -> None:
    """
    Mean team return against the worst-decile team return, one point per variant and seed.

    :param references: summary rows drawn as labelled crosses (e.g. the hand-made policies of ``hazard_policies.py``)
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    markers = "osD^vP*Xh"
    for index, (variant, label) in enumerate(zip(variants, labels, strict=True)):
        by_seed = rows.get(variant, {})
        if not by_seed:
            continue
        xs = [row["return_mean"] for row in by_seed.values()]
        ys = [row["return_worst_decile"] for row in by_seed.values()]
        ax.scatter(xs, ys, marker=markers[index % len(markers)], s=48, label=label)
    for row in references or []:
        ax.scatter([row["return_mean"]], [row["return_worst_decile"]], marker="x", s=64, color="black")
        ax.annotate(
            row["method"],
            (row["return_mean"], row["return_worst_decile"]),
            fontsize=8,
            xytext=(4, 4),
            textcoords="offset points",
        )
    ax.set_xlabel("mean team return")
    ax.set_ylabel("worst-decile team return")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder", type=Path, help="the folder of the eval_<variant>_s<seed> folders")
    parser.add_argument("--variants", nargs="+", required=True, help="variants in the table's order")
    parser.add_argument("--labels", nargs="+", default=None, help="a label per variant (default: the variant)")
    parser.add_argument("--figure", type=Path, default=None, help="write the mean-against-worst-decile figure here")
    parser.add_argument(
        "--policies", type=Path, default=None, help="a results folder of hazard_policies.py: its policies as crosses"
    )
    args = parser.parse_args(argv)
    labels = args.labels or args.variants
    if len(labels) != len(args.variants):
        parser.error(f"--labels needs one label per variant ({len(args.variants)}), got {len(labels)}")
    rows = read_rows(args.folder)
    if not rows:
        parser.error(f"no <variant>_s<seed>.jsonl or eval_<variant>_s<seed>/results.json in {args.folder}")
    print(table(rows, args.variants, labels))
    if args.figure:
        references = json.loads((args.policies / "results.json").read_text())["summary"] if args.policies else None
        figure(rows, args.variants, labels, args.figure, references)
        print(f"figure written to {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
