"""
What a step is worth (docs/environment.md, "One step" and "Metrics"): coverage (step 3), the entropy of the UAVs'
cells (step 5), the team metrics and the two rewards (step 6).

Shapes (N UAVs, K PoIs): ``positions`` (N, 2), ``pois`` (K, 2), ``active`` (N,) bool, ``coverage_scores`` (K,) =
c_t(k), ``covering`` (N, K) bool. Values shared by the team (metrics, entropy, the report's reward) are computed once
per step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "REWARD_MODES",
    "cell_entropy",
    "coverage_credit",
    "coverage_score",
    "covering_pairs",
    "energy_cost",
    "energy_weighted_gain",
    "jain_fairness",
    "report_reward",
    "team_metrics",
]

#: The rewards; the first is the report's (``uav_coverage_v0``), the second v1's.
REWARD_MODES = ("report", "coverage")


def covering_pairs(positions: np.ndarray, pois: np.ndarray, active: np.ndarray, coverage_range: float) -> np.ndarray:
    """
    Which active UAV covers which PoI: (N, K) squared distances in one broadcast.

    :return: (N, K) bool, PoI k within R0 of UAV i and UAV i active
    """
    diff = pois[None, :, :] - positions[:, None, :]
    sq_dist = np.einsum("nkd,nkd->nk", diff, diff)
    return (sq_dist <= coverage_range**2) & active[:, None]


def coverage_score(visits: np.ndarray, t: int, out: np.ndarray | None = None) -> np.ndarray:
    """
    The coverage scores c_t(k) = w(k) / t: the share of the t steps so far in which PoI k was covered.

    :param visits: (..., K) w(k), the steps in which PoI k was covered
    :param t: steps since reset, >= 1
    :param out: where to write them (as ``np.divide``'s)
    """
    return np.divide(visits, t, out=out)


def jain_fairness(score_sum: Any, square_sum: Any, n_pois: int) -> Any:
    """
    Jain's fairness index of K coverage scores, (sum_k c(k))^2 / (K sum_k c(k)^2), 0 where every score is 0.

    :param score_sum: sum_k c(k), a number or an array
    :param square_sum: sum_k c(k)^2, of the same shape
    :param n_pois: K
    :return: f, of that shape (it can exceed 1 by a rounding of the last bit)
    """
    return np.where(square_sum > 0.0, score_sum * score_sum / (n_pois * np.maximum(square_sum, 1e-300)), 0.0)


def coverage_credit(covering: np.ndarray, coverage_scores: np.ndarray, fairness_coef: float) -> np.ndarray:
    """
    Each UAV's credit for this step's weighted coverage (``reward_mode="coverage"``): each covered PoI's worth is
    split equally between the UAVs covering it.

    :param covering: (N, K) bool, PoI k within R0 of UAV i after the move, UAV i active this step
    :param coverage_scores: (K,) c_{t-1}(k), read before this step's update (0 at the first step)
    :param fairness_coef: phi
    :return: (N,) credit: (N / K) sum_k [i covers k] (1 - phi c_{t-1}(k)) / (number of UAVs covering k)
    """
    n_uavs = len(covering)
    weight = 1.0 - fairness_coef * coverage_scores
    weight = weight / np.maximum(covering.sum(axis=0), 1)
    return covering @ weight * (n_uavs / len(weight))


def energy_cost(spent: np.ndarray, energy_coef: float, move_energy: float, max_distance: float) -> np.ndarray:
    """The coverage reward's energy term of each UAV: ``energy_coef`` times its energy this step / (eta l_max)."""
    return energy_coef * spent / (move_energy * max_distance)


def report_reward(
    fairness: float, score_gain: float, step_energy: float, entropy: float, *, entropy_coef: float, eps: float
) -> float:
    """
    The report's shared reward: fairness-weighted coverage gain per unit of energy plus the entropy bonus.

    :param fairness: f_t
    :param score_gain: sum_k c_t(k) - sum_k c_{t-1}(k)
    :param step_energy: the team's energy this step
    :param entropy: the entropy of the active UAVs' cells
    """
    return energy_weighted_gain(fairness, score_gain, step_energy, eps) + entropy_coef * entropy


def energy_weighted_gain(fairness: Any, score_gain: Any, step_energy: Any, eps: float) -> Any:
    """
    The coverage term of the report's reward: f_t * (sum_k c_t(k) - sum_k c_{t-1}(k)) / (e + eps), numbers or arrays.

    :param fairness: f_t
    :param score_gain: the gain of the coverage scores' sum
    :param step_energy: the energy e of the step
    :param eps: epsilon
    """
    return fairness * score_gain / (step_energy + eps)


def cell_entropy(positions: np.ndarray, active: np.ndarray, map_size: int) -> float:
    """
    Entropy of the active UAVs' cell histogram (0 with fewer than two active UAVs).

    :param positions: (N, 2)
    :param active: (N,) bool
    :param map_size: L
    """
    n_active = int(active.sum())
    if n_active <= 1:
        return 0.0
    cells = np.floor(positions[active]).astype(np.int64)
    _, counts = np.unique(cells[:, 0] * map_size + cells[:, 1], return_counts=True)
    p = counts / n_active
    return float(-(p * np.log(p)).sum())


def team_metrics(
    coverage_scores: np.ndarray,
    total_energy_spent: float,
    t: int,
    *,
    n_uavs: int,
    move_energy: float,
    max_distance: float,
    eps: float,
) -> tuple[float, float, float, float]:
    """
    The team metrics after step t (docs/environment.md, "Metrics").

    :param coverage_scores: (K,) c_t(k)
    :param total_energy_spent: the team's energy since reset
    :param t: steps since reset, >= 1
    :return: coverage c_t, Jain's fairness f_t, energy ratio e_t and energy efficiency eta_t
    """
    score_sum = float(coverage_scores.sum())
    k = len(coverage_scores)
    square_sum = float(np.dot(coverage_scores, coverage_scores))
    coverage = score_sum / k
    # Jain's index is <= 1 exactly; min() only removes a last-bit rounding excess.
    fairness = min(float(jain_fairness(score_sum, square_sum, k)), 1.0)
    energy_ratio = total_energy_spent / (n_uavs * t * move_energy * max_distance)
    energy_efficiency = fairness * coverage / (energy_ratio + eps)
    return coverage, fairness, energy_ratio, energy_efficiency
