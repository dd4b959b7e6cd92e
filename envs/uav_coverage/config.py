"""
The env's parameters as one validated object, :class:`UAVCoverageConfig`.

Each parameter's check stands beside its field (the ``check`` of its metadata, a function of ``validation.py``) and
runs whenever the field is set, at construction in the fields' order and on a later assignment; a check that compares
a parameter with an earlier one (R0 <= R, obs_size a multiple of L, what the storm needs) belongs to the later one.
``__post_init__`` then warns about settings without effect and reads what the PoIs and the start positions are.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from ..validation import (
    MAX_MAP_SIZE,
    MAX_OBS_SIZE,
    MAX_STEPS,
    MAX_UAVS,
    check_choice,
    check_int,
    check_number,
    check_points,
    check_step_memory,
    check_zone,
    warn_without_effect,
)
from .dynamics import ACTION_MODES, WALL_MODES
from .observations import POSITION_MARKS
from .pois import resolve_pois
from .rewards import REWARD_MODES

__all__ = ["UAVCoverageConfig", "config_from_old_state"]

#: A field's check: (name, value given, the config with the earlier fields set) -> the value to store
Check = Callable[[str, Any, "UAVCoverageConfig"], Any]


def _checked(default: Any, check: Check) -> Any:
    return field(default=default, metadata={"check": check})


def _real(**bounds: Any) -> Check:
    return lambda name, value, _config: check_number(name, value, **bounds)


def _positive() -> Check:
    return _real(low=0.0, low_open=True)


def _int(low: int, high: int) -> Check:
    return lambda name, value, _config: check_int(name, value, low=low, high=high)


def _choice(choices: tuple[str, ...]) -> Check:
    return lambda name, value, _config: check_choice(name, value, choices)


def _flag(accepted: str) -> Check:
    def check(name: str, value: Any, _config: UAVCoverageConfig) -> bool:
        if not isinstance(value, bool | np.bool_):
            raise TypeError(f"{name} must be {accepted}, got {value!r}")
        return bool(value)

    return check


def _comm_range(name: str, value: Any, config: UAVCoverageConfig) -> float:
    comm_range = check_number(name, value, low=0.0, low_open=True)
    if config.coverage_range > comm_range:
        raise ValueError(
            f"coverage_range must be <= comm_range (R0 <= R), got coverage_range={config.coverage_range!r} "
            f"and comm_range={value!r}"
        )
    return comm_range


def _obs_size(name: str, value: Any, config: UAVCoverageConfig) -> int:
    obs_size = check_int(name, value, low=1, high=MAX_OBS_SIZE)
    if obs_size % config.map_size != 0:
        raise ValueError(f"obs_size must be a positive multiple of map_size={config.map_size}, got {value!r}")
    return obs_size


def _reward_clip(name: str, value: Any, _config: UAVCoverageConfig) -> float | None:
    return None if value is None else check_number(name, value, low=0.0, low_open=True)


def _grounded_penalty(name: str, value: Any, config: UAVCoverageConfig) -> float:
    penalty = check_number(name, value, low=0.0)
    if penalty > 0.0 and config.crash_ground_steps == 0:
        raise ValueError(
            f"grounded_penalty={value!r} needs crash_ground_steps >= 1 (without grounding no UAV is "
            "ever grounded); set crash_ground_steps or leave grounded_penalty at 0"
        )
    return penalty


def _storm_zone(name: str, value: Any, config: UAVCoverageConfig) -> tuple[float, float, float, float] | None:
    return check_zone(name, value, config.map_size)


def _storm_prob(name: str, value: Any, config: UAVCoverageConfig) -> float:
    storm_prob = check_number(name, value, low=0.0, high=1.0)
    if storm_prob > 0.0 and config.storm_zone is None:
        raise ValueError(
            f"storm_prob={value!r} needs a storm_zone (x0, y0, x1, y1) where the storm strikes; set storm_zone "
            "or leave storm_prob at 0"
        )
    if storm_prob > 0.0 and config.crash_ground_steps == 0 and config.crash_energy == 0.0:
        raise ValueError(
            f"storm_prob={value!r} needs crash_ground_steps >= 1 or crash_energy > 0 (a strike costs what a "
            "crash costs, and with both at 0 it would cost nothing); set one of them or leave storm_prob at 0"
        )
    return storm_prob


@dataclass(eq=False)
class UAVCoverageConfig:
    """
    The parameters of a multi-UAV coverage env (N UAVs over an L x L area with K points of interest), checked.

    :param map_size: L, the area is [0, L)^2 in cell units (at most 1024)
    :param n_uavs: N, number of UAVs (at most 1024; with the PoIs and the observation images, a step's arrays must fit
        in 1 GiB each)
    :param pois: ``"grid"`` (the L x L integer lattice), ``"uniform"`` (``n_pois`` points drawn from the seed),
        an array (K, 2) of coordinates, or a grayscale image (path to a PNG/JPEG, or a 2-D array of at least 4 x 4
        pixels; other 2-D arrays are refused as ambiguous)
    :param n_pois: number of PoIs for ``pois="uniform"`` (default L^2); only used there
    :param poi_threshold: for image PoIs, a cell holds a PoI when its mean intensity exceeds this fraction of the
        image's maximum intensity
    :param max_energy: E_max, each UAV's battery at reset
    :param max_distance: l_max, longest move per step
    :param move_energy: eta, energy per unit of distance flown
    :param hover_energy: E_h, energy of a step spent hovering
    :param coverage_range: R0, a PoI within R0 of an active UAV is covered
    :param comm_range: R, an active UAV with no other active UAV within R is disconnected
    :param wall_penalty: p_w, charged for a move that would leave the area
    :param comm_penalty: p_c, charged for each step disconnected
    :param entropy_coef: lambda, weight of the spatial entropy of the UAVs in the shared reward
    :param eps: epsilon in denominators; a UAV is depleted when its energy is <= eps * E_max
    :param max_cycles: T, steps per episode (truncation; at most 10**9)
    :param obs_size: S, observation side in pixels, a positive multiple of L (at most 4096)
    :param start: ``"fixed"`` (drawn once at the first reset, then reused), ``"random"`` (drawn at every reset) or an
        array (N, 2) of start positions
    :param reward_scale: every agent's reward is multiplied by this
    :param reward_clip: if set, rewards are clipped into [-reward_clip, reward_clip]
    :param action_mode: ``"polar"`` (the report's: a = (direction / 2 pi, distance / l_max)) or ``"cartesian"``
        (displacement (dx, dy) = (2 a - 1) l_max, shortened to l_max when longer; a = (0.5, 0.5) hovers)
    :param wall_mode: ``"refuse"`` (the report's: a move that would leave the area is not made and is charged
        ``wall_penalty``) or ``"clip"`` (the UAV stops at the boundary and is charged ``wall_penalty`` times the
        overshoot / l_max, so the penalty grows continuously from 0 with how far the move would have gone out)
    :param reward_mode: ``"report"`` (the report's shared reward: fairness-weighted coverage gain per unit of energy
        plus ``entropy_coef`` times the spatial entropy) or ``"coverage"`` (per-agent credit of order 1: each PoI
        covered this step is worth ``1 - fairness_coef * c_{t-1}(k)``, split equally between the UAVs covering it and
        scaled by N / K, so the agents' rewards sum to N times the team's weighted coverage fraction; minus
        ``energy_coef`` times the UAV's own energy this step / (eta l_max))
    :param fairness_coef: with ``reward_mode="coverage"``, how much less a PoI is worth
        the more it has been covered so far, in [0, 1] (0: every covered PoI counts 1; 1: only the uncovered share of
        its history counts)
    :param energy_coef: with ``reward_mode="coverage"``, the weight of the UAV's own energy (>= 0)
    :param teammate_channel: if True, observations get a fourth channel showing the active teammates within radio
        range R (``comm_range``) of the agent, each on its cell block with its channel-1 value; what a decentralised
        UAV can learn from its links. The state keeps its three channels (it already shows every UAV).
    :param position_mark: how a UAV is drawn on channel 1 of the observations and of the state: ``"cell"`` (the
        report's: its cell's block, so the image tells only which cell it is in) or ``"exact"`` (a square of one
        cell's size centred on its exact position, anti-aliased: each pixel holds the value times the fraction of it
        the square covers, so the mark's centre of mass is the position itself, to the uint8 rounding). Which PoIs a
        disc of radius R0 covers depends on where in its cell the UAV is (29 to 32 lattice PoIs at R0 = 3), so a
        policy that only knows the cell cannot place its disc well
    :param gust_prob: p_g, hazard: the probability that a wind gust hits an active UAV at a step (0, the default, is
        no gusts). A gust pushes the UAV after its own move by a heavy-tailed distance (``gust_scale``,
        ``gust_tail``) in a uniformly random direction; one pushed out of the area stops at the boundary and crashes:
        it is charged ``wall_penalty`` and loses ``crash_energy``
    :param gust_scale: s, the gusts' distance scale: P(distance > x) = (1 + x / s)^(-a)
    :param gust_tail: a, the gusts' tail index (>= 0.5; smaller is heavier: the distance has a finite mean only for
        a > 1 and a finite variance only for a > 2)
    :param crash_energy: E_c, energy a UAV loses when a gust crashes it (never more than it has left); it counts as
        energy spent in the reward and in the energy metric
    :param link_failure_prob: p_f, hazard: the probability that a radio link in range fails at a step, each link on its
        own (0, the default, is no failures); a UAV whose links all fail is disconnected (charged ``comm_penalty``)
    :param crash_ground_steps: k, hazard: a UAV that a gust crashes (or the storm strikes) is grounded for the k steps
        after the crash (0, the default, is never; at most 10**9): it stays where it stopped and does not fly, cover,
        link or spend energy, its observations and teammates' show it as absent, and then it takes off again from
        there. A crash's loss is then spread over k steps of lost coverage instead of one step's energy
        (``crash_energy``)
    :param grounded_penalty: p_d, charged to a grounded UAV at each of its grounded steps (its reward is then
        -``reward_scale`` p_d where a depleted UAV's is 0); needs ``crash_ground_steps`` > 0
    :param show_grounded: if True, a grounded UAV's own observation (and the state) shows its mark with the number of
        grounded steps it has left (1 to k) as its channel-1 value, instead of no mark: where it sits and when it
        flies again are then observable, so its return while grounded is a function of its observation (it stays
        absent from its teammates' teammate channel: it has no links)
    :param storm_zone: hazard: a rectangle (x0, y0, x1, y1) of the area where a storm can strike a UAV down (None, the
        default, is no zone); the same in every episode, like terrain, and drawn in the observations only with
        ``show_storm_zone`` (without it, a policy learns where the zone is from its own position)
    :param storm_prob: p_s, hazard: the probability that an active UAV inside ``storm_zone`` at the end of a step is
        struck (0, the default, is never). A strike does not move the UAV; it is a crash: it loses ``crash_energy``
        and is grounded for ``crash_ground_steps`` (one of the two must be set), counted in the ``crashes``. So the
        zone's PoIs are worth covering on average and costly in the worst case
    :param storm_penalty: p_k, hazard: charged to a struck UAV in the step of the strike (0, the default, is nothing),
        on top of what the crash costs: the strike's cost lands at once, inside a discounted critic's horizon, where
        k grounded steps spread it over the next k steps
    :param show_storm_zone: if True, channel 0 of the observations and of the state shows the storm zone: each pixel
        whose centre lies in ``storm_zone`` holds 128 where its cell holds a PoI and 64 where it does not (instead of
        255 and 0), so the zone is a visible function of the image and not only of the UAV's position; the
        observation space is unchanged (False, the default, draws no zone)
    """

    map_size: int = _checked(16, _int(1, MAX_MAP_SIZE))
    n_uavs: int = _checked(6, _int(1, MAX_UAVS))
    # read with n_pois in __post_init__, once the other parameters are checked
    pois: str | os.PathLike | np.ndarray | list = "grid"
    n_pois: int | None = None
    poi_threshold: float = _checked(0.1, _real(low=0.0, high=1.0, high_open=True))
    max_energy: float = _checked(500.0, _positive())
    max_distance: float = _checked(3.0, _positive())
    move_energy: float = _checked(1.0 / 3.0, _positive())
    hover_energy: float = _checked(0.5, _positive())
    coverage_range: float = _checked(3.0, _positive())
    comm_range: float = _checked(6.0, _comm_range)
    wall_penalty: float = _checked(10.0, _real(low=0.0))
    comm_penalty: float = _checked(1.0, _real(low=0.0))
    entropy_coef: float = _checked(0.1, _real(low=0.0))
    eps: float = _checked(1e-4, _real(low=0.0, high=1.0, low_open=True, high_open=True))
    max_cycles: int = _checked(300, _int(1, MAX_STEPS))
    obs_size: int = _checked(80, _obs_size)
    # read in __post_init__
    start: str | np.ndarray | list = "fixed"
    reward_scale: float = _checked(1.0, _positive())
    reward_clip: float | None = _checked(None, _reward_clip)
    action_mode: str = _checked("polar", _choice(ACTION_MODES))
    wall_mode: str = _checked("refuse", _choice(WALL_MODES))
    reward_mode: str = _checked("report", _choice(REWARD_MODES))
    fairness_coef: float = _checked(0.5, _real(low=0.0, high=1.0))
    energy_coef: float = _checked(0.5, _real(low=0.0))
    teammate_channel: bool = _checked(False, _flag("a bool"))
    position_mark: str = _checked("cell", _choice(POSITION_MARKS))
    # Hazards (all off by default, and then no random number is drawn: v0 and v1 are unchanged)
    gust_prob: float = _checked(0.0, _real(low=0.0, high=1.0))
    gust_scale: float = _checked(1.0, _positive())
    # a >= 0.5: below, a single gust's distance is so heavy-tailed that almost every gust crosses the map
    gust_tail: float = _checked(2.0, _real(low=0.5))
    crash_energy: float = _checked(0.0, _real(low=0.0))
    # p_f < 1: with certain failure there would be no links at all, a comm_range of 0 in disguise
    link_failure_prob: float = _checked(0.0, _real(low=0.0, high=1.0, high_open=True))
    crash_ground_steps: int = _checked(0, _int(0, MAX_STEPS))
    grounded_penalty: float = _checked(0.0, _grounded_penalty)
    show_grounded: bool = _checked(False, _flag("True or False"))
    storm_zone: tuple[float, float, float, float] | None = _checked(None, _storm_zone)
    storm_prob: float = _checked(0.0, _storm_prob)
    storm_penalty: float = _checked(0.0, _real(low=0.0))
    show_storm_zone: bool = _checked(False, _flag("True or False"))

    # --- read from the parameters by __post_init__ ---------------------------------------------------------------------
    #: ``"grid"``, ``"uniform"``, ``"array"`` or ``"image"``
    pois_mode: str = field(init=False, repr=False)
    #: the PoIs (K, 2), or None for uniform ones (drawn at the first reset)
    poi_points: np.ndarray | None = field(init=False, repr=False)
    #: ``"fixed"``, ``"random"`` or ``"array"``
    start_mode: str = field(init=False, repr=False)
    #: the start positions (N, 2) of ``start_mode="array"``, else None
    start_points: np.ndarray | None = field(init=False, repr=False)
    #: whether a hazard is switched on (gusts, link failures or the storm): the env then has a hazard hook
    hazards: bool = field(init=False, repr=False)
    #: channels of an agent's observation: 3, or 4 with the teammate channel
    n_obs_channels: int = field(init=False, repr=False)

    def __setattr__(self, name: str, value: Any) -> None:
        check = _CHECKS.get(name)
        object.__setattr__(self, name, value if check is None else check(name, value, self))

    def __post_init__(self) -> None:
        # Settings that act only with another one: accepted (a sweep may set them beside a zero probability), but said
        crashing = self.gust_prob > 0.0 or self.storm_prob > 0.0
        no_crash = "nothing crashes a UAV without gusts (gust_prob > 0) or a storm (storm_prob > 0)"
        warn_without_effect(
            {
                "storm_zone": (self.storm_zone is not None and self.storm_prob == 0.0, "storm_prob is 0, so no storm strikes"),
                "crash_ground_steps": (self.crash_ground_steps > 0 and not crashing, no_crash),
                "crash_energy": (self.crash_energy > 0.0 and not crashing, no_crash),
                "show_grounded": (self.show_grounded and self.crash_ground_steps == 0, "crash_ground_steps is 0"),
                "storm_penalty": (self.storm_penalty > 0.0 and self.storm_prob == 0.0, "storm_prob is 0, so no storm strikes"),
                "show_storm_zone": (self.show_storm_zone and self.storm_zone is None, "storm_zone is None, there is no zone"),
            },
            stacklevel=4,
        )
        self.hazards = self.gust_prob > 0.0 or self.link_failure_prob > 0.0 or self.storm_prob > 0.0
        self.n_obs_channels = 4 if self.teammate_channel else 3
        check_step_memory(
            "observation images (n_uavs x channels x obs_size^2 bytes)",
            f"n_uavs={self.n_uavs}, obs_size={self.obs_size}",
            self.n_uavs * self.n_obs_channels * self.obs_size**2,
        )
        self.pois_mode, self.poi_points, self.n_pois = resolve_pois(self.pois, self.n_pois, self.map_size, self.poi_threshold)
        n_pois_total = self.n_pois if self.poi_points is None else len(self.poi_points)
        check_step_memory(
            "UAV-PoI distances (n_uavs x PoIs x 16 bytes)",
            f"n_uavs={self.n_uavs} with {n_pois_total} PoIs (pois={self.pois_mode!r}, map_size={self.map_size})",
            self.n_uavs * int(n_pois_total or 0) * 16,
        )
        self.start_points = None
        if isinstance(self.start, str):
            if self.start not in ("fixed", "random"):
                raise ValueError(
                    f"start must be 'fixed', 'random' or an array of shape ({self.n_uavs}, 2), got {self.start!r}"
                )
            self.start_mode = self.start
        else:
            self.start_mode = "array"
            self.start_points = check_points("start", self.start, self.n_uavs, self.map_size)

    def kwargs(self) -> dict[str, Any]:
        """The parameters as given to the constructor (checked: numbers as float or int, the storm zone a tuple)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.init}


_CHECKS: dict[str, Check] = {f.name: f.metadata["check"] for f in fields(UAVCoverageConfig) if "check" in f.metadata}
#: The parameters a core read from its old attributes before it held a config (pickles of that layout)
_OLD_LAYOUT_DERIVED = ("pois_mode", "n_pois", "start_mode", "_start_array", "hazards", "n_obs_channels")


def config_from_old_state(state: dict[str, Any]) -> UAVCoverageConfig:
    """
    The config of a core pickled before the core held one (its parameters were its attributes), for its unpickling.

    :param state: the old core's ``__dict__``; its parameter entries are taken out of it
    :return: the config
    """
    names = [f.name for f in fields(UAVCoverageConfig) if f.init and f.name not in ("pois", "n_pois", "start")]
    # parameters added since that layout take their defaults
    kwargs = {name: state.pop(name) for name in names if name in state}
    pois_mode, n_pois, start_mode, start_points = (state.pop(key) for key in _OLD_LAYOUT_DERIVED[:4])
    for key in _OLD_LAYOUT_DERIVED[4:]:
        state.pop(key)
    # image PoIs were read into points; uniform ones may be drawn already: the core's state keeps them
    pois = pois_mode if pois_mode in ("grid", "uniform") else state["pois"]
    start = start_points if start_mode == "array" else start_mode
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said when the core was built
        config = UAVCoverageConfig(**kwargs, pois=pois, n_pois=n_pois, start=start)
    config.pois_mode = pois_mode
    return config
