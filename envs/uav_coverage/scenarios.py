"""
The tasks of the UAV coverage env as scenarios, in the manner of mpe2's: a scenario says what a task's world is, and
one env class runs any of them. Here a task's world is its parameters, so a scenario is the env's name and the
parameters where the task differs from the defaults of :class:`~.config.UAVCoverageConfig`; ``make_config`` checks
them into a config (mpe2's ``make_world``), ``parallel_env``, ``raw_env`` and ``env`` build the env
(:class:`~.uav_coverage.UAVCoverageEnv`). The rules themselves (the reward, the observation) are the env's, chosen by
the parameters (``reward_mode``, ``position_mark``, ...), so any task's rule can be switched in another.

- :data:`V0`: the report's task (``uav_coverage_v0``), the defaults;
- :data:`V1`: version 1 (``uav_coverage_v1``), :data:`V1_DEFAULTS`: the defaults that learn;
- :data:`TMC2020`: the published setting of Liu et al. (IEEE TMC 2020) on v1's rules, :data:`TMC2020_KWARGS`;
- :data:`HAZARD`: v1 with :data:`HAZARDS`, the hazardous task (``uav_coverage_hazard_cpu_v1``);
- :data:`STORM_TASK`: v1 with :data:`STORM`, the storm task (``uav_coverage_storm_cpu_v1``);
- :data:`STORM_V2_TASK`: v1 with :data:`STORM_V2`, the storm task redesigned for a discounted quantile critic
  (``uav_coverage_storm_cpu_v2``): the zone drawn in the observations, frequent strikes that cost at once.

The env ids this package registers for ``sb3_maddpg``'s command line (``registration.py``) build these scenarios,
some at another ``obs_size``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pettingzoo.utils import wrappers
from pettingzoo.utils.conversions import parallel_to_aec
from pettingzoo.utils.env import AECEnv

from .config import UAVCoverageConfig
from .uav_coverage import UAVCoverageEnv

__all__ = [
    "HAZARD",
    "HAZARDS",
    "SCENARIOS",
    "STORM",
    "STORM_TASK",
    "STORM_V2",
    "STORM_V2_TASK",
    "TMC2020",
    "TMC2020_KWARGS",
    "V0",
    "V1",
    "V1_DEFAULTS",
    "UAVCoverageScenario",
]

#: Where v1's defaults differ from v0's (the other parameters keep v0's defaults).
V1_DEFAULTS: dict[str, Any] = {
    "action_mode": "cartesian",
    "wall_mode": "clip",
    "wall_penalty": 1.0,
    "reward_mode": "coverage",
    "fairness_coef": 0.5,
    "energy_coef": 0.5,
    "comm_penalty": 0.1,
    "start": "random",
    "position_mark": "exact",
    "teammate_channel": True,
}

#: The published setting of Liu et al., "Distributed Energy-Efficient Multi-UAV Navigation for Long-Term Communication
#: Coverage by Deep Reinforcement Learning", IEEE TMC 19(6), 2020 (docs/results.md, "The published setting"), on v1's
#: rules: the paper's geometry and energy, the defaults of ``uav_coverage_tmc_v1``. A step costs hover_energy +
#: (move_energy * l_max - hover_energy) * rho, so 0.5 hovering and 1.0 for a full move of one cell, and the energy
#: metric is e_T / (N T * 1.0) as in the paper.
TMC2020_KWARGS: dict[str, Any] = {
    "map_size": 10,  # 10 x 10 area, the 100 grid PoIs
    "n_uavs": 6,  # the paper's default; its sweep is 3 to 8
    "coverage_range": 3.0,
    "comm_range": 5.0,
    "max_distance": 1.0,  # one PoI spacing (inferred from the paper's figures)
    "move_energy": 1.0,
    "hover_energy": 0.5,
    "max_cycles": 500,
    # 2 pixels per cell: obs_size must be a multiple of map_size, and the CNN (ReportCNN, three 3 x 3 stride-2
    # convolutions) needs at least 15 x 15 pixels, so 10 (1 pixel per cell) is too small and 20 the smallest that fits.
    "obs_size": 20,
}

#: The hazards of the hazardous task (``uav_coverage_hazard_cpu_v1``): wind hits a UAV at 75 % of its steps and
#: pushes it by a Lomax distance of scale 2 cells and tail index 8 (P(d > x) = (1 + x / 2)^-8: median 0.18 cells, one
#: gust in 660 beyond 2.5 cells, one in 12 500 beyond 4.5); one thrown against the boundary crashes and loses 200
#: energy (an energy term of 100 in the reward, most of a team's episode return); each radio link fails at 5 % of the steps.
HAZARDS: dict[str, Any] = {
    "gust_prob": 0.75,
    "gust_scale": 2.0,
    "gust_tail": 8.0,
    "crash_energy": 200.0,
    "link_failure_prob": 0.05,
}

#: The hazards of the storm task (``uav_coverage_storm_cpu_v1``): a storm over the middle 10 x 10 cells of the 16 x 16
#: map strikes each UAV inside it at 0.5 % of its steps (about 4 strikes a 300-step episode for a team placed
#: greedily, which hovers there); a struck UAV is grounded for 20 steps, charged 0.75 a step (about 7 times a
#: hovering UAV's usual reward, so one strike costs 15 of a team return of about 160). Keeping out of the zone loses
#: its inner PoIs (coverage 0.66 against 0.70) and every strike. No gusts (learning under large random pushes failed:
#: docs/results.md), the same link failures as the hazardous task.
STORM: dict[str, Any] = {
    "storm_zone": (3.0, 3.0, 13.0, 13.0),
    "storm_prob": 0.005,
    "crash_ground_steps": 20,
    "grounded_penalty": 0.75,
    "link_failure_prob": 0.05,
}

#: The hazards of the storm task redesigned (``uav_coverage_storm_cpu_v2``), so that a critic that looks about 10 steps
#: ahead (gamma 0.9) sees the storm in its lower tail (docs/environment.md, "Hazards", has the numbers):
#:
#: - the zone, 5 x 5 cells (5, 3)-(10, 8) around the greedy placement's middle spot (7.5, 5.5), is drawn on channel 0
#:   of the observations and the state (``show_storm_zone``), so the risk is a function of the image;
#: - a UAV inside is struck at 7 % of its steps: from a state inside, a strike within 10 steps has probability
#:   1 - 0.93^10 = 0.52, more than twice alpha 0.25;
#: - a strike costs p_k = 0.9 in its own step and grounds the UAV for 3 steps (no grounded penalty): the whole cost
#:   lands inside the horizon, where the old task's 20 grounded steps at -0.75 lay mostly beyond it;
#: - the zone holds PoIs worth covering: without strikes the greedy team hovering there earns 15.6 an episode (0.052
#:   a step) more than one kept out; with them its UAV inside is struck about 17.6 times an episode, each strike
#:   costing the team 0.9 - 0.25 = 0.65 (0.25 the teammates' gain while the struck UAV is grounded), 11.5 on
#:   average: the mean prefers entering, the worst decile (about 23 strikes) and CVaR_0.25 of a 10-step return
#:   (1.25 discounted strikes against 0.60 on average) keeping out.
#:
#: The same link failures as the other hazard tasks; no gusts.
STORM_V2: dict[str, Any] = {
    "storm_zone": (5.0, 3.0, 10.0, 8.0),
    "storm_prob": 0.07,
    "storm_penalty": 0.9,
    "crash_ground_steps": 3,
    "show_storm_zone": True,
    "link_failure_prob": 0.05,
}


class UAVCoverageScenario:
    """
    A task of the UAV coverage env: its name and its parameters over the defaults.

    :param name: the env's name in ``metadata`` (``"uav_coverage_v0"`` or ``"uav_coverage_v1"``)
    :param layers: dicts of parameters, later ones over earlier ones; read at each call, so a change to one of the
        module's dicts (``V1_DEFAULTS``, ...) shows in the envs built after it
    """

    def __init__(self, name: str, *layers: Mapping[str, Any]) -> None:
        self.name = name
        self.layers = layers

    def __repr__(self) -> str:
        return f"UAVCoverageScenario({self.name!r}, {self.defaults!r})"

    @property
    def defaults(self) -> dict[str, Any]:
        """The task's parameters over the config's defaults."""
        return {key: value for layer in self.layers for key, value in layer.items()}

    def make_config(self, **kwargs: Any) -> UAVCoverageConfig:
        """
        :param kwargs: parameters over the task's
        :return: the task's parameters, checked
        """
        return UAVCoverageConfig(**{**self.defaults, **kwargs})

    def parallel_env(self, **kwargs: Any) -> UAVCoverageEnv:
        """
        :param kwargs: ``render_mode`` and any parameter of the config; they override the task's
        :return: the task as a PettingZoo ``ParallelEnv``
        """
        return UAVCoverageEnv(**{**self.defaults, **kwargs}, name=self.name)

    def raw_env(self, **kwargs: Any) -> AECEnv:
        """The task as an AEC env (PettingZoo's ``parallel_to_aec``), without wrappers."""
        return parallel_to_aec(self.parallel_env(**kwargs))

    def env(self, **kwargs: Any) -> AECEnv:
        """The task as a wrapped AEC env (order enforcing)."""
        return wrappers.OrderEnforcingWrapper(self.raw_env(**kwargs))


V0 = UAVCoverageScenario("uav_coverage_v0")
V1 = UAVCoverageScenario("uav_coverage_v1", V1_DEFAULTS)
TMC2020 = UAVCoverageScenario("uav_coverage_v1", V1_DEFAULTS, TMC2020_KWARGS)
HAZARD = UAVCoverageScenario("uav_coverage_v1", V1_DEFAULTS, HAZARDS)
STORM_TASK = UAVCoverageScenario("uav_coverage_v1", V1_DEFAULTS, STORM)
STORM_V2_TASK = UAVCoverageScenario("uav_coverage_v1", V1_DEFAULTS, STORM_V2)
#: The scenarios by short name
SCENARIOS: dict[str, UAVCoverageScenario] = {
    "v0": V0,
    "v1": V1,
    "tmc2020": TMC2020,
    "hazard": HAZARD,
    "storm": STORM_TASK,
    "storm_v2": STORM_V2_TASK,
}
