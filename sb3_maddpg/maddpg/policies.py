"""The decentralised actors and the MADDPG policy (its critics: ``sb3_maddpg.maddpg.critics``)."""

from typing import Any

import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, FlattenExtractor, get_actor_critic_arch
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from torch import nn

from sb3_maddpg.common.actions import action_width, check_action_space, gumbel_max_sample, is_discrete, one_hot_argmax
from sb3_maddpg.common.agent_spaces import AgentSpaces
from sb3_maddpg.common.torch_layers import BatchedMlp, MultiAgentFeatures, ReportCNN
from sb3_maddpg.common.validation import check_bool, check_int, check_net_arch, check_optional_dict, check_subclass
from sb3_maddpg.maddpg.critics import CRITICS, QuantileCriticBase, check_attention_arguments

# The logit of a padded Discrete action: exp(-1e4) is 0 in every float type, and it stays finite (no inf - inf)
_MASKED_LOGIT = -1e4


class MultiAgentActor(nn.Module):
    """
    Decentralised deterministic actors: agent i's action is mu_i(o_i), squashed by tanh into [-1, 1]
    (the policy rescales it to the action space). All agents are evaluated together.

    With a ``Discrete(n)`` action space each actor outputs n logits instead (its "preactivations"), and its action
    for the critics is a one-hot vector: the argmax's here (``forward``, ``squash``), the straight-through
    Gumbel-softmax sample in the actor update, a Gumbel-max sample when exploring (``sb3_maddpg.common.actions``).

    :param observation_space: one agent's observation space
    :param action_space: one agent's action space (Box, or Discrete)
    :param n_agents: number of agents N
    :param net_arch: hidden layer sizes of each actor
    :param activation_fn: activation function
    :param features_extractor_class: features extractor class
    :param features_extractor_kwargs: its keyword arguments
    :param normalize_images: divide image observations by 255
    :param shared: one actor (extractor and MLP) for all agents
    :param critic_features: the critic's per-agent encoders, to read instead of encoders of the actor's own (the
        actor's MLPs then take the critic's encodings as constants: the critic's loss alone trains the encoders).
        Borrowed, not owned: they are not among the actor's parameters, modules or state dict. None (the default)
        gives the actor its own encoders, trained by the actor's loss
    :param observation_mask: for agents with spaces of their own, (N, *obs_shape) booleans marking each agent's own
        observation entries (the others are padding, set to 0 before the encoders); None when nothing is padded
    :param action_mask: (N, action width) booleans marking each agent's own action entries (Box) or actions
        (Discrete); the actor outputs 0 in the others (Box) or never picks them (their logits are masked out)
    :param agent_groups: the group of each agent: the agents of a group share one MLP (each with a first-layer bias
        of its own, an agent-index input); None: every agent its own
    """

    def __init__(
        self,
        observation_space: spaces.Box,
        action_space: spaces.Box | spaces.Discrete,
        n_agents: int,
        net_arch: list[int],
        activation_fn: type[nn.Module],
        features_extractor_class: type[BaseFeaturesExtractor],
        features_extractor_kwargs: dict[str, Any],
        normalize_images: bool,
        shared: bool = False,
        critic_features: MultiAgentFeatures | None = None,
        observation_mask: th.Tensor | None = None,
        action_mask: th.Tensor | None = None,
        agent_groups: tuple[int, ...] | None = None,
    ) -> None:
        super().__init__()
        self.n_agents = n_agents
        self.discrete = is_discrete(action_space)
        self.action_mask: th.Tensor | None
        self.register_buffer("action_mask", action_mask, persistent=False)
        self.reads_critic_features = critic_features is not None
        if critic_features is None:
            self.features = MultiAgentFeatures(
                observation_space,
                n_agents,
                features_extractor_class,
                features_extractor_kwargs,
                normalize_images,
                shared=shared,
                observation_mask=observation_mask,
            )
        else:
            # Kept out of nn.Module's registry: the critic's optimizer, soft update and state dict own these weights
            self.__dict__["features"] = critic_features
        self.mu = BatchedMlp(
            1 if shared else n_agents,
            self.features.features_dim,
            action_width(action_space),
            net_arch,
            activation_fn,
            shared_by=agent_groups,
        )

    def preactivations(self, observations: th.Tensor, critic_features: th.Tensor | None = None) -> th.Tensor:
        """
        :param observations: (B, N, *obs_shape)
        :param critic_features: the critics' encodings of ``observations`` (B, N, F), where the caller has them (the
            update does): actors that read the critics' encoders take them instead of encoding again; ignored by
            actors with encoders of their own
        :return: the actions before the tanh squashing, (B, N, action_dim); the logits (B, N, n) for Discrete(n)
        """
        if self.reads_critic_features:
            # The critic's encodings are the actor's input, not its parameters: no gradient flows back into them
            if critic_features is None:
                with th.no_grad():
                    critic_features = self.features(observations)
            return self.own_entries(self.mu(critic_features.detach()))
        return self.own_entries(self.mu(self.features(observations)))

    def own_entries(self, preactivations: th.Tensor) -> th.Tensor:
        """
        Keep each agent's own action entries: with padded action spaces, the others become 0 (Box: a tanh of 0, an
        action of 0 that SuperSuit cuts off before the env) or a logit of -1e4 (Discrete: a probability of 0).

        :param preactivations: (B, N, action width)
        :return: the same shape; ``preactivations`` itself when nothing is padded
        """
        if self.action_mask is None:
            return preactivations
        return preactivations.masked_fill(~self.action_mask, _MASKED_LOGIT if self.discrete else 0.0)

    def agent_mean(self, values: th.Tensor) -> th.Tensor:
        """
        Each agent's mean of a per-entry statistic of its outputs over the batch and its own entries.

        :param values: (B, N, action width), e.g. the squared preactivations
        :return: (N,)
        """
        if self.action_mask is None:
            return values.mean(dim=(0, 2))
        own = self.action_mask.to(values.dtype)
        return (values * own).sum(dim=(0, 2)) / (own.sum(dim=1) * values.shape[0])

    def squash(self, preactivations: th.Tensor) -> th.Tensor:
        """
        The deterministic actions, as the critics read them, from the actors' outputs.

        :param preactivations: (B, N, action_dim) from ``preactivations``
        :return: their tanh, in [-1, 1]; for Discrete actions, the one-hot vectors of the logits' argmax
        """
        if self.discrete:
            return one_hot_argmax(preactivations)
        return th.tanh(preactivations)

    def forward(self, observations: th.Tensor, critic_features: th.Tensor | None = None) -> th.Tensor:
        """
        :param observations: (B, N, *obs_shape)
        :param critic_features: the critics' encodings of ``observations``, if at hand (see ``preactivations``)
        :return: actions in [-1, 1], (B, N, action_dim); one-hot vectors (B, N, n) for Discrete(n)
        """
        return self.squash(self.preactivations(observations, critic_features))


class MADDPGPolicy(BasePolicy):
    """
    Policy of MADDPG: decentralised actors, centralised quantile critics and their target networks.

    ``predict`` takes SB3's row layout, (n_copies * N, *obs_shape) with row = copy * N + agent, and gives row r
    the action of actor r mod N. With a ``Discrete`` action space it returns integers: the argmax of the actor's
    logits with ``deterministic=True``, a sample of their softmax (Gumbel-max) otherwise.

    :param observation_space: one agent's observation space (a Box)
    :param action_space: one agent's action space (a Box, or a Discrete)
    :param lr_schedule: learning rate schedule
    :param n_agents: number of agents N
    :param share_actor: one actor for all agents instead of one per agent
    :param share_features_extractor: the actors read the critics' encoders instead of their own: each observation is
        encoded once per update for actors and critics (and once for both target networks), the encoders are
        trained by the critics' loss only, and the actors take the encodings as constants (as DrQ and SAC-AE share
        one encoder between actor and critic). Note that SB3's TD3 and SAC, with the same flag, train the shared
        extractor through the actor's loss instead. False (the default) gives actors and critics their own encoders
    :param n_quantiles: number of quantiles of each critic (1 gives a classic scalar critic)
    :param n_critics: quantile networks per agent's critic: 1 for MADDPG, 2 for MATD3's twin critics
    :param net_arch: hidden layers of actors and critics: a list, or a dict with keys ``pi`` and ``qf``
        (default [64, 64], as in the MADDPG paper)
    :param activation_fn: activation function
    :param features_extractor_class: features extractor (``FlattenExtractor`` for MlpPolicy, ``ReportCNN`` for CnnPolicy)
    :param features_extractor_kwargs: keyword arguments of the extractor
    :param normalize_images: divide image observations by 255
    :param optimizer_class: optimizer of actors and critics
    :param optimizer_kwargs: its keyword arguments, without the learning rate
    :param agent_groups: the group of each agent (0, 1, ...): the actors of a group's agents share one MLP and their
        critics share their networks, each agent with a first-layer bias of its own (an agent-index input); encoders
        stay per agent. The algorithm's ``groups`` argument sets it. None: every agent its own networks
    :param mean_anchored_quantiles: critics with a mean head (``MultiAgentQuantileCritic``'s ``mean_head``); MADDPG's
        argument of the same name passes it
    :param agent_spaces: each agent's own spaces where they differ (``observation_space`` and ``action_space`` are
        then the padded ones, see ``sb3_maddpg.common.agent_spaces``); the algorithm passes the VecEnv's. None where
        all agents have ``observation_space`` and ``action_space``
    :param critic: the critics' design (``sb3_maddpg.maddpg.critics``): ``"joint"`` (classic MADDPG: each critic reads
        every agent's encoding and action in one concatenation) or ``"attention"`` (each critic reads its own agent on
        a path of its own and its teammates through attention; a size that does not grow with the team's)
    :param critic_kwargs: keyword arguments of the critic's design (``"attention"``: ``embed_dim``, 64, and
        ``n_heads``, 4); the joint critic takes none
    """

    actor: MultiAgentActor
    actor_target: MultiAgentActor
    critic: QuantileCriticBase
    critic_target: QuantileCriticBase

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Schedule,
        n_agents: int = 1,
        share_actor: bool = False,
        share_features_extractor: bool = False,
        n_quantiles: int = 50,
        n_critics: int = 1,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        features_extractor_class: type[BaseFeaturesExtractor] = FlattenExtractor,
        features_extractor_kwargs: dict[str, Any] | None = None,
        normalize_images: bool = True,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        mean_anchored_quantiles: bool = False,
        agent_groups: tuple[int, ...] | None = None,
        agent_spaces: AgentSpaces | None = None,
        critic: str = "joint",
        critic_kwargs: dict[str, Any] | None = None,
    ) -> None:
        if not isinstance(observation_space, spaces.Box):
            raise TypeError(f"MADDPGPolicy accepts a Box observation space (vector or image), got {observation_space}")
        check_action_space(action_space, "MADDPGPolicy")
        self.critic_class, self.critic_design_kwargs = _check_critic(critic, critic_kwargs)
        # As in the algorithms: what SB3's BasePolicy stores is checked as it is handed over, the rest where it is stored
        super().__init__(
            observation_space,
            action_space,
            check_subclass("features_extractor_class", features_extractor_class, BaseFeaturesExtractor),
            check_optional_dict("features_extractor_kwargs", features_extractor_kwargs),
            optimizer_class=check_subclass("optimizer_class", optimizer_class, th.optim.Optimizer),
            optimizer_kwargs=check_optional_dict("optimizer_kwargs", optimizer_kwargs),
            # The tanh output is rescaled to a Box's bounds; Discrete actions are integers
            squash_output=isinstance(action_space, spaces.Box),
            normalize_images=check_bool("normalize_images", normalize_images),
        )
        self.n_agents = n_agents = check_int("n_agents", n_agents, low=1)
        self.share_actor = check_bool("share_actor", share_actor)
        self.share_features_extractor = check_bool("share_features_extractor", share_features_extractor)
        self.n_quantiles = check_int("n_quantiles", n_quantiles, low=1)
        self.n_critics = check_int("n_critics", n_critics, low=1)
        self.net_arch = [64, 64] if net_arch is None else check_net_arch(net_arch)
        self.activation_fn = check_subclass("activation_fn", activation_fn, nn.Module)
        self.agent_spaces = agent_spaces
        self.mean_anchored_quantiles = mean_anchored_quantiles
        self.critic_name = critic
        self.agent_groups = _check_agent_groups(agent_groups, n_agents, self.share_actor)
        observation_mask, action_mask = _padding_masks(agent_spaces, observation_space, action_space, n_agents)
        common = dict(
            observation_space=observation_space,
            action_space=action_space,
            n_agents=n_agents,
            activation_fn=self.activation_fn,
            features_extractor_class=self.features_extractor_class,
            features_extractor_kwargs=self.features_extractor_kwargs,
            normalize_images=self.normalize_images,
        )
        masks = dict(observation_mask=observation_mask, action_mask=action_mask, agent_groups=self.agent_groups)
        actor_arch, critic_arch = get_actor_critic_arch(self.net_arch)
        self.actor_kwargs = dict(common, net_arch=actor_arch, shared=self.share_actor, **masks)
        self.critic_kwargs = dict(
            common,
            net_arch=critic_arch,
            n_quantiles=self.n_quantiles,
            n_critics=self.n_critics,
            mean_head=mean_anchored_quantiles,
            **masks,
            **self.critic_design_kwargs,
        )
        self._build(lr_schedule)

    def _build(self, lr_schedule: Schedule) -> None:
        if self.share_features_extractor:
            # The critics first: the actors borrow their encoders (the target actors the target critics')
            self._build_critics(lr_schedule)
            self._build_actors(lr_schedule, self.critic.features, self.critic_target.features)
        else:
            self._build_actors(lr_schedule)
            self._build_critics(lr_schedule)
        # Target networks always use their (copied) BatchNorm running statistics
        self.actor_target.train(False)
        self.critic_target.train(False)

    def _build_actors(
        self,
        lr_schedule: Schedule,
        critic_features: MultiAgentFeatures | None = None,
        target_critic_features: MultiAgentFeatures | None = None,
    ) -> None:
        self.actor = MultiAgentActor(**self.actor_kwargs, critic_features=critic_features)
        self.actor_target = MultiAgentActor(**self.actor_kwargs, critic_features=target_critic_features)
        self.actor_target.load_state_dict(self.actor.state_dict())
        self.actor.optimizer = self._make_optimizer(self.actor, lr_schedule(1))  # type: ignore[assignment]

    def _build_critics(self, lr_schedule: Schedule) -> None:
        self.critic = self.critic_class(**self.critic_kwargs)
        self.critic_target = self.critic_class(**self.critic_kwargs)
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic.optimizer = self._make_optimizer(self.critic, lr_schedule(1))  # type: ignore[assignment]

    def _make_optimizer(self, module: nn.Module, learning_rate: float) -> th.optim.Optimizer:
        # Adam and AdamW take one fused kernel for all parameters (fused=True, on CPU and GPU alike) unless the
        # optimizer_kwargs choose an implementation: the default for-loop form costs a dozen small operations
        # per parameter tensor, most of the optimizer's time at MADDPG's network sizes. The arithmetic is the same.
        kwargs = dict(self.optimizer_kwargs)
        if self.optimizer_class in (th.optim.Adam, th.optim.AdamW) and not {"fused", "foreach"} & kwargs.keys():
            kwargs["fused"] = True
        return self.optimizer_class(module.parameters(), lr=learning_rate, **kwargs)  # type: ignore[call-arg]

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(
            dict(
                n_agents=self.n_agents,
                share_actor=self.share_actor,
                share_features_extractor=self.share_features_extractor,
                n_quantiles=self.n_quantiles,
                n_critics=self.n_critics,
                net_arch=self.net_arch,
                activation_fn=self.activation_fn,
                lr_schedule=self._dummy_schedule,  # not needed to load the policy alone
                optimizer_class=self.optimizer_class,
                optimizer_kwargs=self.optimizer_kwargs,
                features_extractor_class=self.features_extractor_class,
                features_extractor_kwargs=self.features_extractor_kwargs,
                agent_spaces=self.agent_spaces,
                mean_anchored_quantiles=self.mean_anchored_quantiles,
                agent_groups=self.agent_groups,
                critic=self.critic_name,
                critic_kwargs=self.critic_design_kwargs or None,
            )
        )
        return data

    def forward(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        return self._predict(observation, deterministic=deterministic)

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        """
        Actions of SB3's rows. Box actions: deterministic (``deterministic`` is ignored, exploration noise is added
        outside). Discrete actions: the argmax of the logits with ``deterministic``, else a Gumbel-max sample of their
        softmax (the exploration of the rollouts).

        :param observation: (R, *obs_shape) with R a multiple of N, row r belonging to agent r mod N
        :return: actions in [-1, 1], (R, action_dim); for Discrete actions the integers (R,)
        """
        assert isinstance(observation, th.Tensor)
        n_rows = observation.shape[0]
        if n_rows % self.n_agents != 0:
            raise ValueError(
                f"predict expects rows of whole joint observations (a multiple of n_agents={self.n_agents} rows, "
                f"row = copy * n_agents + agent), got {n_rows} rows"
            )
        joint = observation.view(n_rows // self.n_agents, self.n_agents, *observation.shape[1:])
        if self.actor.discrete:
            logits = self.actor.preactivations(joint).reshape(n_rows, -1)
            indices = logits.argmax(dim=-1) if deterministic else gumbel_max_sample(logits)
            return indices + int(self.action_space.start)  # type: ignore[attr-defined]
        return self.actor(joint).reshape(n_rows, -1)

    def set_training_mode(self, mode: bool) -> None:
        """
        Train mode (BatchNorm uses batch statistics and updates running ones) or eval mode (acting).
        Target networks stay in eval mode.

        :param mode: True for training mode
        """
        # Called before every VecEnv step and every update, so the mode flips twice per step: setting the flag of a
        # flat list of modules costs a fraction of nn.Module.train's recursive walk. Modules with their own train()
        # are still called.
        if mode == self.training and self.actor.training == mode and self.critic.training == mode:
            return
        cached = getattr(self, "_mode_modules", None)
        if cached is None or cached[0] is not self.actor or cached[1] is not self.critic:
            cached = self._mode_modules = (self.actor, self.critic, [*self.actor.modules(), *self.critic.modules()])
        for module in cached[2]:
            if type(module).train is nn.Module.train:
                module.training = mode
            else:
                module.train(mode)
        self.training = mode


MlpPolicy = MADDPGPolicy


class CnnPolicy(MADDPGPolicy):
    """
    MADDPG policy for image observations: ``MADDPGPolicy`` whose default features extractor is the report's CNN
    (``ReportCNN``). Parameters as in ``MADDPGPolicy``.
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Schedule,
        n_agents: int = 1,
        share_actor: bool = False,
        share_features_extractor: bool = False,
        n_quantiles: int = 50,
        n_critics: int = 1,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        features_extractor_class: type[BaseFeaturesExtractor] = ReportCNN,
        features_extractor_kwargs: dict[str, Any] | None = None,
        normalize_images: bool = True,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        mean_anchored_quantiles: bool = False,
        agent_groups: tuple[int, ...] | None = None,
        agent_spaces: AgentSpaces | None = None,
        critic: str = "joint",
        critic_kwargs: dict[str, Any] | None = None,
    ) -> None:
        super().__init__(
            observation_space,
            action_space,
            lr_schedule,
            n_agents=n_agents,
            share_actor=share_actor,
            share_features_extractor=share_features_extractor,
            n_quantiles=n_quantiles,
            n_critics=n_critics,
            net_arch=net_arch,
            activation_fn=activation_fn,
            features_extractor_class=features_extractor_class,
            features_extractor_kwargs=features_extractor_kwargs,
            normalize_images=normalize_images,
            optimizer_class=optimizer_class,
            optimizer_kwargs=optimizer_kwargs,
            mean_anchored_quantiles=mean_anchored_quantiles,
            agent_groups=agent_groups,
            agent_spaces=agent_spaces,
            critic=critic,
            critic_kwargs=critic_kwargs,
        )


def _padding_masks(
    agent_spaces: AgentSpaces | None, observation_space: spaces.Box, action_space: spaces.Space, n_agents: int
) -> tuple[th.Tensor | None, th.Tensor | None]:
    """
    The observation and action masks of agents with spaces of their own, checked against the padded spaces.

    :return: (N, *obs_shape) and (N, action width) booleans; (None, None) when nothing is padded
    """
    if agent_spaces is None or agent_spaces.homogeneous:
        return None, None
    if not isinstance(agent_spaces, AgentSpaces):
        raise TypeError(f"agent_spaces must be an AgentSpaces or None, got {type(agent_spaces).__name__}")
    if agent_spaces.n_agents != n_agents:
        raise ValueError(f"agent_spaces describes {agent_spaces.n_agents} agents, but n_agents={n_agents}")
    observation_mask = agent_spaces.observation_mask()
    obs_shape = tuple(observation_space.shape)
    if observation_mask.shape[1:] != obs_shape and len(obs_shape) == 3:
        # Images that SB3 transposed to channel-first (VecTransposeImage): (N, H, W, C) -> (N, C, H, W)
        observation_mask = observation_mask.transpose(0, 3, 1, 2)
    if observation_mask.shape[1:] != obs_shape:
        raise ValueError(
            f"the agents' padded observation shape {agent_spaces.padded_observation_shape} does not match the "
            f"observation space {observation_space}"
        )
    action_mask = agent_spaces.action_mask()
    if action_mask.shape[1] != action_width(action_space):
        raise ValueError(f"the agents' widest action ({action_mask.shape[1]}) does not match the action space {action_space}")
    return th.as_tensor(observation_mask), th.as_tensor(action_mask)


def _check_agent_groups(agent_groups: Any, n_agents: int, share_actor: bool) -> tuple[int, ...] | None:
    """Agent groups as the policy takes them: one index per agent, numbered 0, 1, ... (the algorithm's ``groups``)."""
    if agent_groups is None:
        return None
    groups = tuple(int(group) for group in agent_groups)
    if len(groups) != n_agents or set(groups) != set(range(max(groups) + 1)):
        raise ValueError(f"agent_groups must give each of the {n_agents} agents a group 0, 1, ..., got {agent_groups!r}")
    if share_actor:
        raise ValueError("share_actor=True already shares one actor between all agents; leave groups unset with it")
    return groups


def _check_critic(critic: Any, critic_kwargs: Any) -> tuple[type[QuantileCriticBase], dict[str, Any]]:
    """The critic class named by ``critic`` and its keyword arguments, checked where the policy takes them."""
    if not isinstance(critic, str) or critic not in CRITICS:
        raise ValueError(f"critic must be one of {sorted(CRITICS)}, got {critic!r}")
    if critic_kwargs is None:
        return CRITICS[critic], {}
    if not isinstance(critic_kwargs, dict):
        raise TypeError(f"critic_kwargs must be a dict or None, got {type(critic_kwargs).__name__}")
    accepted = {"attention": ("embed_dim", "n_heads")}.get(critic, ())
    unknown = sorted(set(critic_kwargs) - set(accepted))
    if unknown:
        raise ValueError(f"critic={critic!r} takes the critic_kwargs {list(accepted)}, got unknown keys {unknown}")
    if critic == "attention":
        check_attention_arguments(critic_kwargs.get("embed_dim", 64), critic_kwargs.get("n_heads", 4))
    return CRITICS[critic], dict(critic_kwargs)
