"""MADDPG with centralised quantile critics and a CVaR actor objective, on the multi-agent off-policy base."""

import contextlib
import functools
import warnings
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.common.utils import FloatSchedule, get_parameters_by_name

from sb3_maddpg.common.actions import straight_through_gumbel_softmax
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.diagnostics import own_action_candidates, own_action_value_range
from sb3_maddpg.common.distributional import cvar, mean_anchored_quantile_loss, quantile_huber_loss
from sb3_maddpg.common.graphed_update import GraphedUpdate, set_learning_rate
from sb3_maddpg.common.groups import agent_groups, check_groups
from sb3_maddpg.common.model_files import MADDPG_KEYS
from sb3_maddpg.common.noise import current_noise_std
from sb3_maddpg.common.off_policy_algorithm import MultiAgentOffPolicyAlgorithm
from sb3_maddpg.common.validation import (
    check_actor_learning_rate,
    check_bool,
    check_cvar_alpha,
    check_int,
    check_max_grad_norm,
    check_mean_loss,
    check_number,
)
from sb3_maddpg.maddpg.critics import QuantileCriticBase
from sb3_maddpg.maddpg.gradient_step import GradientStepStats, batch_mean
from sb3_maddpg.maddpg.policies import CnnPolicy, MADDPGPolicy, MlpPolicy, MultiAgentActor

SelfMADDPG = TypeVar("SelfMADDPG", bound="MADDPG")

# |pre-tanh| above atanh(0.99): the output is within 1 % of a bound of the action space
_SATURATED_PREACTIVATION = float(np.arctanh(0.99))
# train/own_action_range is measured on the batch of every this many-th update (a few critic passes without gradient)
OWN_ACTION_RANGE_INTERVAL = 200


class MADDPG(MultiAgentOffPolicyAlgorithm):
    """
    Multi-Agent DDPG with centralised quantile critics and a CVaR_alpha actor objective.

    Decentralised actors mu_i(o_i) (one per agent, or one shared); centralised critics Z_i(o, a) with ``n_quantiles``
    outputs at the midpoints tau_j = (j + 0.5) / n, trained with the quantile Huber loss (kappa ``quantile_kappa``) towards
    r_i + gamma (1 - d) Z_i'(o', a'), a'_j = mu_j'(o'_j); actor i maximises CVaR_alpha(Z_i(o, a)) with
    a_i = mu_i(o_i) and the other agents' actions from the batch (MADDPG: Lowe et al. 2017, https://arxiv.org/abs/1706.02275;
    quantile critics: QR-DQN, Dabney et al. 2018, https://arxiv.org/abs/1710.10044). With several critic networks per
    agent (``policy_kwargs=dict(n_critics=2)``, what ``MATD3`` does) the target takes the smaller of the target
    networks' values at each quantile level.

    **Discrete actions** (``Discrete(n)``, e.g. MPE2's default) follow the MADDPG paper's Gumbel-softmax: each actor
    outputs n logits, the env receives integers, the critics and the buffer one-hot vectors; the actor loss scores the
    straight-through Gumbel-softmax sample, the rollouts explore by sampling the logits (``action_noise`` is refused),
    the target actors give the one-hot argmax, and target policy smoothing is not applied (docs/algorithm.md, 6b).

    The environment is an SB3 VecEnv with one row per agent and copy, row = copy * n_agents + agent
    (see ``make_multiagent_vec_env``); the team, the timestep (one joint step of one environment copy), the rollout
    loop, the replay buffer and saving are ``MultiAgentOffPolicyAlgorithm``'s. This class holds MADDPG's arguments,
    its networks, its two losses, one gradient step and ``train``.

    :param policy: the policy model to use (MlpPolicy, CnnPolicy, ...)
    :param env: the VecEnv to learn from (can be None to load a trained model)
    :param learning_rate: learning rate of the Adam optimizers (actors and critics), or a schedule of the
        progress remaining (from 1 to 0)
    :param buffer_size: replay buffer size in joint transitions (timesteps)
    :param learning_starts: timesteps of uniformly random actions before learning starts
    :param batch_size: joint transitions per gradient update
    :param tau: soft update coefficient of the target networks ("Polyak update", between 0 and 1)
    :param gamma: discount factor
    :param train_freq: update the model every ``train_freq`` VecEnv steps; or a tuple like ``(5, "step")`` or,
        with a single environment copy, ``(2, "episode")``
    :param gradient_steps: gradient steps after each rollout; -1 does as many as timesteps collected
    :param action_noise: exploration noise added to the actions rescaled to [-1, 1]; None gives the decaying Gaussian
        noise (``DecayingGaussianNoise``: standard deviation 1.0 decaying towards 0.1); Box actions only (Discrete
        actions explore by sampling the actors' logits)
    :param replay_buffer_class: replay buffer class (default ``MultiAgentReplayBuffer``)
    :param replay_buffer_kwargs: keyword arguments of the replay buffer
    :param cvar_alpha: CVaR level alpha in (0, 1] of the actor objective; 1 is risk-neutral (the mean)
    :param cvar_alpha_anneal_steps: the risk level anneals linearly from 1 (the mean) at timestep 0 to ``cvar_alpha``
        at this timestep, and stays there (as CeSoR's, Greenberg et al., NeurIPS 2022: a risk-averse gradient from the
        start ignores the good outcomes not yet learned). Counted in timesteps, so a resumed run continues it exactly;
        0, the default, uses ``cvar_alpha`` from the start. Logged as ``train/cvar_alpha``
    :param actor_reg: weight of the penalty on the actors' squared pre-tanh outputs, added to each actor loss.
        It keeps the tanh away from saturation, where its gradient vanishes and an actor can get stuck at a bound
        of the action space (the MADDPG authors' implementation uses 1e-3); 0, the default, turns it off
    :param policy_delay: the actors and the target networks are updated once every ``policy_delay`` critic
        updates (TD3's delayed policy update; 1, the default, updates them at every step as in MADDPG)
    :param critic_warmup_steps: gradient steps of critic-only updates before the first actor update, so that the
        actors start following a critic that has already fitted the data (0, the default, starts both together)
    :param actor_learning_rate: learning rate of the actors' optimizer (a number or a schedule); None, the default,
        uses ``learning_rate`` for actors and critics alike
    :param max_grad_norm: if set, the gradient norm of each update (critics, then actors) is clipped to this value
    :param target_policy_noise: standard deviation of the Gaussian noise added to the target actors' actions in the
        critic targets (TD3's target policy smoothing; 0, the default, turns it off as in MADDPG)
    :param target_noise_clip: limit of the absolute value of that noise
    :param gumbel_temperature: temperature (> 0) of the straight-through Gumbel-softmax of the actor update with
        Discrete actions: lower makes the soft sample whose gradient is used closer to the one-hot sample (less
        biased, noisier gradient), higher smoother; it changes neither the sampled actions nor anything with Box
        actions (default 1.0, as in the MADDPG paper's code)
    :param mean_anchored_quantiles: with ``n_quantiles > 1``: each critic network has a mean output of its own beside
        the quantiles' deviations from it; the mean is fitted with the scalar critic's TD loss and the quantile loss
        fits only the deviations, through the output layer alone (``mean_anchored_quantile_loss``), so that a
        risk-neutral actor follows the scalar critic's value. False, the default, is QR-DQN's loss on plain quantiles
    :param mean_loss: the loss of the critics' mean (the scalar critic, or the mean of ``mean_anchored_quantiles``):
        ``"huber"``, the default (kappa 1), or ``"squared"``, TD3's squared TD error, where rare large rewards must count
        in full (the Huber fit weighs a crash of -100 once in ten steps as about -1); refused for plain quantiles
    :param quantile_kappa: the quantile Huber loss's threshold kappa (> 0) for ``n_quantiles > 1``; 1, the default, is
        QR-DQN's. Where the returns spread by about kappa or less the fit is an expectile's and the tail shrinks at
        every bootstrap: take e.g. 0.01 for rewards of order 0.1 to 1 where the tail matters (docs/algorithm.md)
    :param share_actor: one actor shared by all agents instead of one actor per agent
    :param groups: parameter sharing inside groups of agents with the same spaces: ``"teams"`` (the agents of each
        team by PettingZoo's naming, ``adversary_0``, ``adversary_1``, ... one group) or a list of groups of agent
        names (agents not listed keep their own). The agents of a group share one actor MLP and one critic
        network (each agent with a first-layer bias of its own, an agent-index input); their encoders stay their own.
        None, the default: every agent its own actor and critic
    :param cuda_graph: capture each kind of gradient step (critics only; critics, actors and targets) as a CUDA
        graph on its first use and replay it afterwards: one launch per update instead of hundreds of kernel
        launches. Needs ``device="cuda"`` and a fixed batch size (another batch size is captured again); the
        optimizers become capturable. False, the default, runs the same step eagerly
    :param bf16_autocast: run the forward passes of the update under bfloat16 autocast: convolutions and matrix
        products in bfloat16 (about 3 significant digits), while the quantile loss and the CVaR are computed in
        float32 from the networks' outputs, and the parameters and the optimizer state stay float32. Faster on GPUs
        with bfloat16 units; off by default
    :param compile_quantile_loss: on CPU, compute the critics' quantile Huber loss with a kernel compiled by
        ``torch.compile`` (``quantile_huber_loss(compiled=True)``): about 3x faster at 25 quantiles and batch 256
        (MPE2's simple_spread: 1.1x the timesteps per CPU second), equal up to float rounding; its first update
        compiles for about 15 s and needs a C++ compiler (without one: a warning and the eager loss). Off by default
    :param flush_denormals: flush denormal floats to zero on the CPU while ``learn`` runs (a speed-up where weights
        get no gradient; ``MultiAgentOffPolicyAlgorithm``); True by default
    :param n_agents: number of agents; read from the env's ``n_agents`` attribute when None
    :param stats_window_size: window size of the rollout logging (episodes)
    :param tensorboard_log: the log location for TensorBoard (if None, no logging)
    :param policy_kwargs: additional arguments of the policy (``n_quantiles``, ``net_arch``,
        ``features_extractor_class``, ...)
    :param verbose: verbosity level: 0 no output, 1 info messages, 2 debug messages
    :param seed: seed for the pseudo random generators
    :param device: device (cpu, cuda, ...) on which the code should run; "auto" uses the GPU if possible
    :param _init_setup_model: whether or not to build the networks at the creation of the instance
    """

    saved_model_keys: ClassVar[tuple[str, ...]] = MADDPG_KEYS
    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": MlpPolicy,
        "CnnPolicy": CnnPolicy,
    }
    policy: MADDPGPolicy
    actor: MultiAgentActor
    actor_target: MultiAgentActor
    critic: QuantileCriticBase
    critic_target: QuantileCriticBase

    def __init__(
        self,
        policy: str | type[MADDPGPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = 1e-3,
        buffer_size: int = 1_000_000,
        learning_starts: int = 100,
        batch_size: int = 256,
        tau: float = 0.01,
        gamma: float = 0.95,
        train_freq: int | tuple[int, str] = 1,
        gradient_steps: int = 1,
        action_noise: ActionNoise | None = None,
        replay_buffer_class: type[ReplayBuffer] | None = None,
        replay_buffer_kwargs: dict[str, Any] | None = None,
        cvar_alpha: float = 1.0,
        cvar_alpha_anneal_steps: int = 0,
        actor_reg: float = 0.0,
        policy_delay: int = 1,
        critic_warmup_steps: int = 0,
        actor_learning_rate: float | Schedule | None = None,
        max_grad_norm: float | None = None,
        target_policy_noise: float = 0.0,
        target_noise_clip: float = 0.5,
        gumbel_temperature: float = 1.0,
        mean_anchored_quantiles: bool = False,
        mean_loss: str = "huber",
        quantile_kappa: float = 1.0,
        share_actor: bool = False,
        groups: str | list[list[str]] | None = None,
        cuda_graph: bool = False,
        bf16_autocast: bool = False,
        compile_quantile_loss: bool = False,
        flush_denormals: bool = True,
        n_agents: int | None = None,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ) -> None:
        super().__init__(
            policy,
            env,
            learning_rate,
            buffer_size,
            learning_starts,
            batch_size,
            tau,
            gamma,
            train_freq,
            gradient_steps,
            action_noise=action_noise,
            replay_buffer_class=replay_buffer_class,
            replay_buffer_kwargs=replay_buffer_kwargs,
            n_agents=n_agents,
            policy_kwargs=policy_kwargs,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            verbose=verbose,
            device=device,
            seed=seed,
            flush_denormals=flush_denormals,
        )
        # Each argument checked where it is stored, then the combinations; before any network is built
        self.cvar_alpha = check_cvar_alpha(cvar_alpha)
        self.cvar_alpha_anneal_steps = check_int("cvar_alpha_anneal_steps (0: no annealing)", cvar_alpha_anneal_steps, low=0)
        self.actor_reg = check_number("actor_reg (0 turns the penalty off)", actor_reg, low=0.0)
        self.policy_delay = check_int("policy_delay", policy_delay, low=1)
        self.critic_warmup_steps = check_int("critic_warmup_steps", critic_warmup_steps, low=0)
        self.actor_learning_rate = check_actor_learning_rate(actor_learning_rate)
        self.max_grad_norm = check_max_grad_norm(max_grad_norm)
        self.target_policy_noise = check_number("target_policy_noise", target_policy_noise, low=0.0)
        self.target_noise_clip = check_number("target_noise_clip", target_noise_clip, low=0.0)
        self.gumbel_temperature = check_number(
            "gumbel_temperature (the Gumbel-softmax temperature, default 1.0)", gumbel_temperature, low=0.0, low_open=True
        )
        self.mean_anchored_quantiles = check_bool("mean_anchored_quantiles", mean_anchored_quantiles)
        self.mean_loss = check_mean_loss(mean_loss)
        self.quantile_kappa = check_number(
            "quantile_kappa (the quantile Huber loss's threshold)", quantile_kappa, low=0.0, low_open=True
        )
        self.share_actor = check_bool("share_actor", share_actor)
        self.groups = check_groups(groups)
        self.cuda_graph = check_bool("cuda_graph", cuda_graph)
        self.bf16_autocast = check_bool("bf16_autocast", bf16_autocast)
        self.compile_quantile_loss = check_bool("compile_quantile_loss", compile_quantile_loss)
        self._check_argument_combinations()

        if _init_setup_model:
            self._setup_model()

    def _check_argument_combinations(self) -> None:
        """Refuse arguments that are each accepted but not together (or that belong to the algorithm, not the policy)."""
        algorithm = type(self).__name__
        if self.cvar_alpha_anneal_steps > 0 and self.cuda_graph:
            raise ValueError(
                "cvar_alpha_anneal_steps changes the risk level as training goes, which a CUDA graph cannot follow (it "
                "records one): leave cuda_graph=False or cvar_alpha_anneal_steps=0"
            )
        if self.groups is not None and self.share_actor:
            raise ValueError("share_actor=True shares one actor between all agents; give groups or share_actor, not both")
        if "share_actor" in self.policy_kwargs:
            raise ValueError(
                f"share_actor is an argument of {algorithm}, not a policy kwarg: use {algorithm}(..., share_actor=True)"
            )
        if "mean_anchored_quantiles" in self.policy_kwargs:
            raise ValueError(
                f"mean_anchored_quantiles is an argument of {algorithm} (it sets the loss and the critics' mean head), "
                f"not a policy kwarg: use {algorithm}(..., mean_anchored_quantiles=True)"
            )
        if self.cuda_graph and self.device.type != "cuda":
            raise ValueError(
                f"cuda_graph=True records the update as a CUDA graph and needs device='cuda', got device={self.device!s}; "
                "leave cuda_graph=False on other devices"
            )

    def _policy_arguments(self) -> dict[str, Any]:
        assert self.agent_names is not None
        return dict(
            share_actor=self.share_actor,
            mean_anchored_quantiles=self.mean_anchored_quantiles,
            agent_groups=agent_groups(self.groups, self.agent_names, self.agent_spaces),
        )

    def _setup_model(self) -> None:
        super()._setup_model()
        if self.mean_loss == "squared" and self.policy.n_quantiles > 1 and not self.mean_anchored_quantiles:
            raise ValueError(
                f"mean_loss='squared' fits a mean, and {self.policy.n_quantiles} plain quantiles have none: use it with "
                "n_quantiles=1 or with mean_anchored_quantiles=True, or keep mean_loss='huber'"
            )
        if self.policy.n_quantiles == 1 and self.quantile_kappa != 1.0:
            message = (
                f"quantile_kappa={self.quantile_kappa} has no effect with n_quantiles=1 (the scalar critic uses mean_loss)"
            )
            warnings.warn(message, UserWarning, stacklevel=2)
        self.actor_lr_schedule = (
            self.lr_schedule if self.actor_learning_rate is None else FloatSchedule(self.actor_learning_rate)
        )
        self._create_aliases()
        # Online and target tensors in matching order, for the fused soft update; BatchNorm running statistics are
        # copied to the targets at every target update (see TD3)
        self._online_parameters = [*self.critic.parameters(), *self.actor.parameters()]
        self._target_parameters = [*self.critic_target.parameters(), *self.actor_target.parameters()]
        self._online_batch_norm_stats = [
            *get_parameters_by_name(self.critic, ["running_"]),
            *get_parameters_by_name(self.actor, ["running_"]),
        ]
        self._target_batch_norm_stats = [
            *get_parameters_by_name(self.critic_target, ["running_"]),
            *get_parameters_by_name(self.actor_target, ["running_"]),
        ]
        self._graphed_update: GraphedUpdate | None = None
        if self.cuda_graph and self.device.type == "cuda":
            self._graphed_update = GraphedUpdate(self._gradient_step, [self.critic.optimizer, self.actor.optimizer])
        elif self.cuda_graph:
            # a model trained with CUDA graphs, loaded on another device: the same update, run eagerly
            warnings.warn(f"cuda_graph=True needs CUDA; this model is on {self.device}, so its updates run eagerly")

    def _create_aliases(self) -> None:
        self.actor = self.policy.actor
        self.actor_target = self.policy.actor_target
        self.critic = self.policy.critic
        self.critic_target = self.policy.critic_target

    def current_cvar_alpha(self) -> float:
        """
        The risk level of the actor objective at the current timestep: ``cvar_alpha``, or during the annealing
        (``cvar_alpha_anneal_steps``) the value on the line from 1 at timestep 0 to ``cvar_alpha``.
        """
        if self.num_timesteps >= self.cvar_alpha_anneal_steps:  # also without annealing (0 steps)
            return self.cvar_alpha
        return 1.0 + (self.cvar_alpha - 1.0) * self.num_timesteps / self.cvar_alpha_anneal_steps

    def critic_loss(self, replay_data: MultiAgentReplayBufferSamples) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """
        Per-agent critic loss on a batch (no optimizer step).

        :param replay_data: a batch of B joint transitions
        :return: the loss of each agent's critic (N,) (the sum over its networks), the quantiles of each critic's
            first network on the batch's actions (B, N, n_quantiles), and the critic-side encodings of the
            observations (B, N, F), which the actor loss reuses
        """
        present, next_present = self._presence(replay_data)
        with th.no_grad():
            # Target distribution (docs/algorithm.md, section 4, step 1): r_i + gamma (1 - d) Z_i'(o', a'),
            # a'_j = mu_j'(o'_j) from the target actors (for Discrete actions the one-hot argmax). The target critics
            # encode o' once; target actors that read the critics' encoders reuse them
            next_features = self.critic_target.encode(replay_data.next_observations)  # (B, N, F)
            next_actions = self.actor_target(replay_data.next_observations, next_features)  # (B, N, A)
            if self.target_policy_noise > 0.0 and not self.actor_target.discrete:
                # TD3's target policy smoothing: the target is the critic's value around the target action (not for
                # one-hot actions, which have no neighbourhood the critic has seen)
                noise = next_actions.new_empty(next_actions.shape).normal_(0.0, self.target_policy_noise)
                noise = noise.clamp(-self.target_noise_clip, self.target_noise_clip)
                next_actions = (next_actions + noise).clamp(-1.0, 1.0)
            if next_present is not None:
                # An agent that has left acts no more: no action of its own reaches any critic
                next_actions = next_actions * next_present.unsqueeze(-1)
            # With several critic networks (MATD3's twins): the smaller value at each quantile level (clipped double Q)
            next_quantiles = self.critic_target.all_quantiles_from_features(next_features, next_actions).min(dim=0).values
            not_done = 1.0 - replay_data.dones.unsqueeze(-1)  # (B, 1, 1): terminations only, not truncations
            if present is not None:
                # An agent's return ends where it leaves the episode: (B, N, 1)
                not_done = not_done * (1.0 - present * (1.0 - next_present)).unsqueeze(-1)
            target_quantiles = replay_data.rewards.unsqueeze(-1) + not_done * self.gamma * next_quantiles

        # Each agent's observation is encoded once; every critic reads all encodings
        features = self.critic.encode(replay_data.observations)  # (B, N, F)
        actions = self._present_actions(replay_data.actions, present)
        # With mean-anchored quantiles, the deviations' loss trains only the output layer: the layers below and the
        # encoders learn from the mean's TD error alone, as a scalar critic's do
        all_quantiles = self.critic.all_quantiles_from_features(
            features, actions, shape_gradient=not self.mean_anchored_quantiles
        )  # (n_critics, B, N, n_q)
        # Quantile regression (QR-DQN): quantile Huber loss, kappa = 1, at the midpoints, or its mean-anchored form,
        # whose mean is fitted with the Huber or the squared TD error (mean_loss; with one quantile only that term);
        # mean over the batch (in float32 also under bf16 autocast); each critic network is fitted to the same target
        if self.mean_anchored_quantiles or self.mean_loss == "squared":
            loss_fn = functools.partial(
                mean_anchored_quantile_loss,
                kappa=self.quantile_kappa,
                squared_mean=self.mean_loss == "squared",
                compiled=self.compile_quantile_loss,
            )
        else:
            # one quantile is the scalar critic: its Huber mean keeps kappa 1
            kappa = self.quantile_kappa if self.policy.n_quantiles > 1 else 1.0
            loss_fn = functools.partial(quantile_huber_loss, kappa=kappa, compiled=self.compile_quantile_loss)
        losses = [batch_mean(loss_fn(quantiles.float(), target_quantiles.float()), present) for quantiles in all_quantiles]
        return sum(losses[1:], losses[0]), all_quantiles[0], features  # (N,), (B, N, n_q), (B, N, F)

    def actor_loss(
        self, replay_data: MultiAgentReplayBufferSamples, features: th.Tensor, preactivations: th.Tensor | None = None
    ) -> th.Tensor:
        """
        Per-agent actor loss: -CVaR_alpha(Z_i(o, a)) where a_i = mu_i(o_i) and a_j (j != i) come from the batch,
        plus ``actor_reg`` times the mean squared pre-tanh output of actor i. For Discrete actions a_i is the
        straight-through Gumbel-softmax sample of actor i's logits, and the penalty is on the logits (as in the MADDPG
        authors' code).

        :param replay_data: a batch of joint transitions
        :param features: critic-side encodings of ``replay_data.observations``, (B, N, F) (treated as constants)
        :param preactivations: the actors' pre-tanh outputs on ``replay_data.observations`` (B, N, A), if already
            computed; computed here otherwise
        :return: loss of each agent, (N,); loss i depends only on actor i's output
        """
        if preactivations is None:
            preactivations = self.actor.preactivations(replay_data.observations)  # (B, N, A)
        if self.actor.discrete:
            # MADDPG paper, discrete actions: one-hot forward, the gradient of the relaxed sample (Gumbel-softmax)
            policy_actions = straight_through_gumbel_softmax(preactivations, self.gumbel_temperature)
        else:
            policy_actions = th.tanh(preactivations)
        # Critic i scores the batch's joint action with a_i = mu_i(o_i) in place of the batch's a_i
        present, _ = self._presence(replay_data)
        actions = self._present_actions(replay_data.actions, present)
        quantiles = self.critic.quantiles_with_own_actions(features, actions, policy_actions)  # (B, N, n_q)
        regularisation = self.actor.agent_mean(preactivations.float().pow(2))  # (N,), over each agent's own entries
        return -batch_mean(cvar(quantiles.float(), self.current_cvar_alpha()), present) + self.actor_reg * regularisation

    def _presence(self, replay_data: MultiAgentReplayBufferSamples) -> tuple[th.Tensor | None, th.Tensor | None]:
        """
        With agents that leave (``departures``): whether each agent is in the episode at o and at o', (B, N) each,
        read from the last entry of its observations (``KeepDepartedAgents``); (None, None) otherwise.
        """
        if not self.departures:
            return None, None
        return replay_data.observations[..., -1].float(), replay_data.next_observations[..., -1].float()

    @staticmethod
    def _present_actions(actions: th.Tensor, present: th.Tensor | None) -> th.Tensor:
        """The joint actions with those of agents that have left set to 0 (they act no more), (B, N, A)."""
        return actions if present is None else actions * present.unsqueeze(-1)

    def _clip_gradients(self, module: th.nn.Module) -> None:
        if self.max_grad_norm is not None:
            th.nn.utils.clip_grad_norm_(module.parameters(), self.max_grad_norm)

    def _autocast(self) -> Any:
        """The forward passes' autocast context: bfloat16 when ``bf16_autocast``, otherwise none."""
        if not self.bf16_autocast:
            return contextlib.nullcontext()
        # No cast cache: each weight is cast once per region anyway, and a CUDA graph must not record cached casts
        return th.autocast(device_type=self.device.type, dtype=th.bfloat16, cache_enabled=False)

    def _gradient_step(
        self, replay_data: MultiAgentReplayBufferSamples, update_actor: bool, update_targets: bool
    ) -> GradientStepStats:
        """
        One gradient step on one batch: the critics; then, if ``update_actor``, the actors; then, if
        ``update_targets``, the soft target updates. Nothing in it waits for the device or branches on a tensor's
        value, so the same code runs eagerly and inside a CUDA graph (``cuda_graph=True``).

        :param replay_data: a batch of joint transitions
        :param update_actor: take an actor step after the critic step
        :param update_targets: soft-update the target networks at the end
        :return: the step's per-agent statistics (the actor's only with an actor step)
        """
        # Critics: the sum of the per-critic losses gives each critic the gradient of its own loss
        with self._autocast():
            critic_loss, current_quantiles, features = self.critic_loss(replay_data)
        self.critic.optimizer.zero_grad(set_to_none=True)
        critic_loss.sum().backward()
        self._clip_gradients(self.critic)
        self.critic.optimizer.step()
        with th.no_grad():
            current_quantiles = current_quantiles.detach().float()
            # The population standard deviation over the quantiles, written out: torch's std kernel takes 7x as long
            # over 25 quantiles on CPU (0.17 against 0.02 ms for simple_spread's batch, 2 % of an update)
            deviations = current_quantiles - current_quantiles.mean(dim=2, keepdim=True)
            stats = GradientStepStats(
                critic_loss=critic_loss.detach(),
                q_mean=current_quantiles.mean(dim=(0, 2)),
                cvar=cvar(current_quantiles, self.current_cvar_alpha()).mean(dim=0),
                q_spread=deviations.square().mean(dim=2).sqrt().mean(dim=0),
            )

        if update_actor:
            # Actor i maximises CVaR_alpha of Z_i with a_i = mu_i(o_i), after the critic step as in TD3.
            # The critics' encodings of this step's observations are reused (detached) instead of encoding them
            # again; actors that read the critics' encoders take them as their input too.
            with self._autocast():
                preactivations = self.actor.preactivations(replay_data.observations, features)
                actor_loss = self.actor_loss(replay_data, features.detach(), preactivations)
            self.actor.optimizer.zero_grad(set_to_none=True)
            actor_loss.sum().backward(inputs=list(self.actor.parameters()))
            self._clip_gradients(self.actor)
            self.actor.optimizer.step()
            with th.no_grad():
                preactivations = preactivations.detach().float()
                if self.actor.discrete:
                    # A (nearly) deterministic categorical policy no longer explores where it is
                    saturated = (th.softmax(preactivations, dim=-1).amax(dim=-1) > 0.99).float().mean(dim=0)
                else:
                    # Saturation: where tanh passes (almost) no gradient, an actor can get stuck at a bound
                    saturated = self.actor.agent_mean((preactivations.abs() > _SATURATED_PREACTIVATION).float())
                stats = stats._replace(
                    actor_loss=actor_loss.detach(),
                    actor_saturation=saturated,
                    actor_preactivation=self.actor.agent_mean(preactivations.abs()),
                )

        if update_targets:
            # Soft target updates (as SB3's polyak_update, in one fused call per network); BatchNorm running
            # statistics are copied (see SB3 GH issue #996)
            with th.no_grad():
                th._foreach_lerp_(self._target_parameters, self._online_parameters, self.tau)
                for running, running_target in zip(self._online_batch_norm_stats, self._target_batch_norm_stats, strict=True):
                    running_target.copy_(running)
        return stats

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        # Switch to train mode (this affects batch norm / dropout)
        self.policy.set_training_mode(True)
        learning_rate = self.lr_schedule(self._current_progress_remaining)
        set_learning_rate(self.critic.optimizer, learning_rate)
        self.logger.record("train/learning_rate", learning_rate)
        actor_lr = self.actor_lr_schedule(self._current_progress_remaining)
        set_learning_rate(self.actor.optimizer, actor_lr)
        self.logger.record("train/actor_learning_rate", actor_lr)
        self.logger.record("train/cvar_alpha", self.current_cvar_alpha())
        assert self.replay_buffer is not None

        steps: list[GradientStepStats] = []
        for _ in range(gradient_steps):
            self._n_updates += 1
            replay_data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)
            # Actors and targets once every policy_delay critic updates (TD3); no actor update during the warm-up
            update_targets = self._n_updates % self.policy_delay == 0
            update_actor = update_targets and self._n_updates > self.critic_warmup_steps
            step = self._gradient_step if self._graphed_update is None else self._graphed_update.step
            steps.append(step(replay_data, update_actor, update_targets))
            if self._n_updates % OWN_ACTION_RANGE_INTERVAL == 0:
                self._record_per_agent("own_action_range", self.own_action_range(replay_data).cpu().numpy())
                self.policy.set_training_mode(True)

        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if gradient_steps == 0:
            return
        # The mean of each statistic over the steps that have it (the actor's: the steps with an actor update),
        # moved to the host in one transfer: (n_statistics, N)
        names, columns = [], []
        for name in GradientStepStats._fields:
            values = [getattr(stats, name) for stats in steps if getattr(stats, name) is not None]
            if values:
                names.append(name)
                columns.append(th.stack(values).float().mean(dim=0))
        stats_np = th.stack(columns).cpu().numpy()
        for row, key in enumerate(names):
            self._record_per_agent(key, stats_np[row], with_mean=key in ("critic_loss", "actor_loss", "actor_saturation"))
        noise_std = current_noise_std(self.action_noise)
        if noise_std is not None:
            self.logger.record("train/noise_std", noise_std)

    def _record_per_agent(self, key: str, values: np.ndarray, with_mean: bool = True) -> None:
        """Log ``train/<key>_<agent>`` for each agent, and with ``with_mean`` their mean as ``train/<key>``."""
        assert self.agent_names is not None
        for i, name in enumerate(self.agent_names):
            self.logger.record(f"train/{key}_{name}", float(values[i]))
        if with_mean:
            self.logger.record(f"train/{key}", float(values.mean()))

    def own_action_range(self, replay_data: MultiAgentReplayBufferSamples) -> th.Tensor:
        """
        How far each critic's value moves with its own agent's action on a batch: the mean over the batch of the range
        of critic i's mean value over a fixed set of candidate actions of agent i, the teammates keeping the batch's
        actions (``sb3_maddpg.common.diagnostics``). Logged as ``train/own_action_range_<agent>``. Evaluated with the
        networks in eval mode (no BatchNorm statistics move) and without touching the random state, so training is
        the same with or without it; the caller restores the training mode.

        :param replay_data: a batch of joint transitions
        :return: (N,)
        """
        self.policy.set_training_mode(False)
        with th.no_grad():
            present, _ = self._presence(replay_data)
            features = self.critic.encode(replay_data.observations)
            candidates = own_action_candidates(self.critic.action_dim, self.actor.discrete, self.device)
            actions = self._present_actions(replay_data.actions, present)
            return own_action_value_range(self.critic, features, actions, candidates, present)

    def _excluded_save_params(self) -> list[str]:
        return [
            *super()._excluded_save_params(),
            "actor",
            "critic",
            "actor_target",
            "critic_target",
            "_online_parameters",
            "_target_parameters",
            "_online_batch_norm_stats",
            "_target_batch_norm_stats",
            "_graphed_update",
        ]

    def _get_torch_save_params(self) -> tuple[list[str], list[str]]:
        state_dicts = ["policy", "actor.optimizer", "critic.optimizer"]
        return state_dicts, []
