"""
The centralised quantile critics of MADDPG and MATD3, a choice of the policy (``critic=``):

- ``"joint"`` (``MultiAgentQuantileCritic``, the default; classic MADDPG): each critic reads one concatenation of
  every agent's encoding and action;
- ``"attention"`` (``AttentionQuantileCritic``, after MAAC): each critic reads its own agent's encoding and action on a
  path of its own and its teammates through attention, with a size that does not depend on the team's.

Both return the same quantities to the algorithm, so MADDPG and MATD3 train either without knowing which.
"""

from typing import Any

import torch as th
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from sb3_maddpg.common.actions import action_width
from sb3_maddpg.common.torch_layers import BatchedLinear, BatchedMlp, MultiAgentFeatures
from sb3_maddpg.common.validation import check_int


class QuantileCriticBase(nn.Module):
    """
    What every multi-agent quantile critic shares: one critic-side encoder per agent (each observation is encoded
    once per update, whatever the number of critics that read it), the masks of padded action entries, and the
    quantile networks' output layer with its optional mean head. A subclass builds ``quantile_nets``, a
    ``BatchedMlp`` with one model per critic network (network c of agent i is model ``c * N + i``), and defines how
    each network's input is made.

    With ``n_critics > 1`` (MATD3's twin critics) each agent has ``n_critics`` quantile networks on the same
    encodings, as SB3's ``ContinuousCritic`` puts its ``n_critics`` Q-networks on one features extractor. The methods
    that return one value per agent (``forward``, ``quantiles_from_features``, ``quantiles_with_own_actions``) use
    the first network of each agent, as SB3's ``q1_forward``; ``all_quantiles`` returns every network's.

    :param observation_space: one agent's observation space
    :param action_space: one agent's action space (a Discrete(n) one is read as one-hot vectors of width n)
    :param n_agents: number of agents N
    :param n_quantiles: number of quantiles per critic
    :param net_arch: hidden layer sizes of each critic's quantile MLP
    :param activation_fn: activation function
    :param features_extractor_class: features extractor class
    :param features_extractor_kwargs: its keyword arguments
    :param normalize_images: divide image observations by 255
    :param n_critics: quantile networks per agent (1 for MADDPG, 2 for MATD3's twin critics)
    :param observation_mask: (N, *obs_shape) booleans marking each agent's own observation entries, or None (see
        ``MultiAgentActor``)
    :param action_mask: (N, action width) booleans marking each agent's own action entries, or None: the critics read
        0 in the others, whatever the batch or the target policy smoothing put there
    :param mean_head: with ``n_quantiles > 1``, each network outputs its mean mu and n deviations d_j from one more
        output row, and its quantiles are mu + d_j - mean(d): the mean is a value of its own, and the deviations (the
        distribution's shape) can be trained without moving the layers that the mean is computed from
        (``shape_gradient=False`` in ``all_quantiles_from_features``). MADDPG's ``mean_anchored_quantiles``
    :param agent_groups: the group of each agent: the critics of a group's agents share their weights (network c of
        each, with a first-layer bias of its own); None: every agent its own
    """

    quantile_nets: BatchedMlp

    def __init__(
        self,
        observation_space: spaces.Box,
        action_space: spaces.Box | spaces.Discrete,
        n_agents: int,
        n_quantiles: int,
        net_arch: list[int],
        activation_fn: type[nn.Module],
        features_extractor_class: type[BaseFeaturesExtractor],
        features_extractor_kwargs: dict[str, Any],
        normalize_images: bool,
        n_critics: int = 1,
        observation_mask: th.Tensor | None = None,
        action_mask: th.Tensor | None = None,
        mean_head: bool = False,
        agent_groups: tuple[int, ...] | None = None,
    ) -> None:
        super().__init__()
        self.n_agents = n_agents
        self.n_quantiles = n_quantiles
        self.n_critics = n_critics
        self.mean_head = mean_head and n_quantiles > 1
        self.features = MultiAgentFeatures(
            observation_space,
            n_agents,
            features_extractor_class,
            features_extractor_kwargs,
            normalize_images,
            observation_mask=observation_mask,
        )
        self.action_mask: th.Tensor | None
        self.register_buffer("action_mask", action_mask, persistent=False)
        self.action_dim = action_width(action_space)
        self.n_outputs = n_quantiles + 1 if self.mean_head else n_quantiles
        # The first network of each agent: models 0 .. N-1
        self._first_critics = slice(0, n_agents)
        self._build_networks(net_arch, activation_fn, self._shared_by(agent_groups))

    def _build_networks(self, net_arch: list[int], activation_fn: type[nn.Module], shared_by: tuple[int, ...] | None) -> None:
        """
        Build the design's layers, ``quantile_nets`` among them (after the encoders, in a fixed order: the order in
        which their weights are drawn).

        :param net_arch: hidden layer sizes of the quantile MLPs
        :param activation_fn: activation function
        :param shared_by: the weights each network uses (``_shared_by``), None: its own
        """
        raise NotImplementedError

    def _shared_by(self, agent_groups: tuple[int, ...] | None) -> tuple[int, ...] | None:
        """With groups, network c of agent i uses the weights c * G + (group of i), G the number of groups."""
        if agent_groups is None:
            return None
        n_groups = max(agent_groups) + 1
        return tuple(c * n_groups + group for c in range(self.n_critics) for group in agent_groups)

    def encode(self, observations: th.Tensor) -> th.Tensor:
        """
        :param observations: (B, N, *obs_shape)
        :return: features (B, N, F), one encoding per agent, shared by all critics
        """
        return self.features(observations)

    def quantiles_from_features(self, features: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """
        The first network of each agent's critic.

        :param features: (B, N, F) from ``encode``
        :param actions: joint actions seen by every critic, (B, N, A); or one joint action per critic,
            (B, N_critics = N, N, A), where ``actions[:, i]`` is the joint action critic i scores
        :return: quantiles (B, N, n_quantiles), ``[:, i]`` from critic i
        """
        raise NotImplementedError

    def all_quantiles_from_features(self, features: th.Tensor, actions: th.Tensor, shape_gradient: bool = True) -> th.Tensor:
        """
        Every network of every agent's critic on the joint actions ``actions``.

        :param features: (B, N, F) from ``encode``
        :param actions: joint actions seen by every critic, (B, N, A)
        :param shape_gradient: with a mean head, False keeps the gradient of the deviations out of every layer but the
            output layer (and out of the encoders): only the mean trains the layers it is computed from
        :return: quantiles (n_critics, B, N, n_quantiles), ``[c, :, i]`` from network c of critic i
        """
        raise NotImplementedError

    def quantiles_with_own_actions(self, features: th.Tensor, actions: th.Tensor, own_actions: th.Tensor) -> th.Tensor:
        """
        The quantiles that the actor update needs: critic i (its first network) scores the joint action ``actions``
        with agent i's own action replaced by ``own_actions[:, i]``.

        :param features: (B, N, F) from ``encode``
        :param actions: the joint actions of the batch, (B, N, A)
        :param own_actions: the actions that replace each agent's own, (B, N, A)
        :return: quantiles (B, N, n_quantiles), ``[:, i]`` from critic i
        """
        raise NotImplementedError

    def _quantiles_from(
        self, hidden: th.Tensor, start: int, models: slice | None = None, shape_gradient: bool = True
    ) -> th.Tensor:
        """
        The quantile networks from layer ``start`` on, model-major: (M, B, width) -> (M, B, n_quantiles).

        With a mean head, output 0 is the mean mu and outputs 1..n the deviations d_j: the quantiles are
        mu + d_j - mean(d), whose mean is mu.
        """
        if not self.mean_head:
            return self.quantile_nets.model_major_from(hidden, start=start, models=models)
        output_layer = len(self.quantile_nets.net) - 1
        last_hidden = self.quantile_nets.model_major_from(hidden, start=start, models=models, stop=output_layer)
        outputs = self.quantile_nets.model_major_from(last_hidden, start=output_layer, models=models)
        if not shape_gradient:
            shape_outputs = self.quantile_nets.model_major_from(last_hidden.detach(), start=output_layer, models=models)
            outputs = th.cat([outputs[..., :1], shape_outputs[..., 1:]], dim=-1)
        deviations = outputs[..., 1:]
        return outputs[..., :1] + deviations - deviations.mean(dim=-1, keepdim=True)

    def _own_actions(self, actions: th.Tensor) -> th.Tensor:
        """Joint actions (B, N, A) or (B, N_critics, N, A) with every padded entry set to 0."""
        if self.action_mask is None:
            return actions
        return actions.masked_fill(~self.action_mask, 0.0)

    def forward(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """
        :param observations: (B, N, *obs_shape)
        :param actions: (B, N, A) in [-1, 1]
        :return: quantiles (B, N, n_quantiles) of each agent's first critic network
        """
        return self.quantiles_from_features(self.encode(observations), actions)

    def all_quantiles(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """
        :param observations: (B, N, *obs_shape)
        :param actions: (B, N, A) in [-1, 1]
        :return: quantiles (n_critics, B, N, n_quantiles) of every critic network
        """
        return self.all_quantiles_from_features(self.encode(observations), actions)


class MultiAgentQuantileCritic(QuantileCriticBase):
    """
    Centralised quantile critics (``critic="joint"``, classic MADDPG): critic i maps every agent's observation and
    action to ``n_quantiles`` values Z_i(o, a)_j, the return distribution's quantiles at the midpoints
    tau_j = (j + 0.5) / n.

    Every critic reads all N encodings: the input of each critic is [f_1, ..., f_N, a_1, ..., a_N], so its own
    agent's action is A of N (F + A) inputs and its first layer grows with N. The N critic MLPs run as one batched
    network. Parameters as in ``QuantileCriticBase``.
    """

    def _build_networks(self, net_arch: list[int], activation_fn: type[nn.Module], shared_by: tuple[int, ...] | None) -> None:
        input_dim = self.n_agents * (self.features.features_dim + self.action_dim)
        n_models = self.n_critics * self.n_agents
        self.quantile_nets = BatchedMlp(n_models, input_dim, self.n_outputs, net_arch, activation_fn, shared_by=shared_by)

    def quantiles_from_features(self, features: th.Tensor, actions: th.Tensor) -> th.Tensor:
        batch_size, n_agents = features.shape[:2]
        actions = self._own_actions(actions)
        if actions.dim() == 3:
            # Every critic reads the same input: one (B, N*F + N*A) tensor, broadcast to the critics without a copy
            hidden = self._first_layer(self._joint_input(features, actions), self._first_critics)
            return self._quantiles_from(hidden, start=1, models=self._first_critics).transpose(0, 1)
        joint_features = features.flatten(1).unsqueeze(1).expand(batch_size, n_agents, -1)
        # (B, N_critics, N*F + N*A)
        critic_inputs = th.cat([joint_features, actions.flatten(2)], dim=2)
        return self._quantiles_from(critic_inputs.transpose(0, 1), start=0, models=self._first_critics).transpose(0, 1)

    def all_quantiles_from_features(self, features: th.Tensor, actions: th.Tensor, shape_gradient: bool = True) -> th.Tensor:
        batch_size, n_agents = features.shape[:2]
        hidden = self._first_layer(self._joint_input(features, self._own_actions(actions)))
        quantiles = self._quantiles_from(hidden, start=1, shape_gradient=shape_gradient)  # (n_critics * N, B, n_q)
        return quantiles.view(self.n_critics, n_agents, batch_size, -1).transpose(1, 2)

    def quantiles_with_own_actions(self, features: th.Tensor, actions: th.Tensor, own_actions: th.Tensor) -> th.Tensor:
        """
        Equal to ``quantiles_from_features`` on the N mixed joint actions, without building them: critic i's input
        differs from the shared one only in agent i's action block, and its first layer is linear
        (``BatchedLinear.forward_with_block_changes``). Parameters as in ``QuantileCriticBase``.
        """
        n_agents = actions.shape[1]
        actions, own_actions = self._own_actions(actions), self._own_actions(own_actions)
        change = (own_actions - actions).transpose(0, 1)  # (N, B, A)
        first_action_row = n_agents * features.shape[-1]  # the joint input is [f_1, ..., f_N, a_1, ..., a_N]
        hidden = self.quantile_nets.first_layer.forward_with_block_changes(
            self._joint_input(features, actions), change, start=first_action_row, models=self._first_critics
        )
        return self._quantiles_from(hidden, start=1, models=self._first_critics).transpose(0, 1)

    @staticmethod
    def _joint_input(features: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """(B, N*F + N*A): every agent's features, then every agent's action."""
        return th.cat([features.flatten(1), actions.flatten(1)], dim=1)

    def _first_layer(self, joint_input: th.Tensor, models: slice | None = None) -> th.Tensor:
        """The critics' first linear layer on one shared input (B, D): (M, B, width), model-major."""
        first = self.quantile_nets.first_layer
        n_models = first.n_models if models is None else len(range(first.n_models)[models])
        return first.forward_model_major(joint_input.unsqueeze(0).expand(n_models, -1, -1), models)


class AttentionQuantileCritic(QuantileCriticBase):
    """
    Per-agent quantile critics that see their own agent on a path of its own and the teammates through attention
    (``critic="attention"``; after MAAC, Iqbal & Sha, "Actor-Attention-Critic for Multi-Agent Reinforcement
    Learning", ICML 2019, written here for batched quantile networks). For network c of agent i:

    - own path: h = act(W_own [f_i, a_i]) (E numbers), weights of agent i's own (or of its group);
    - teammates: each agent j is embedded as e_j = act(W_emb [f_j, a_j]); agent i asks with the query W_q f_i (its
      observation only, so the weights do not move with its own action) and reads
      ctx = sum over j != i of softmax_j(q . W_k e_j / sqrt(d)) act(W_v e_j), in ``n_heads`` heads of d = E / heads;
      W_emb, W_q, W_k and W_v are one set per network c, shared by every agent's critic;
    - quantiles: an MLP (``net_arch``) on [h, ctx].

    So agent i's action is A of the own path's F + A inputs whatever the team's size, a critic's parameter count does
    not grow with N, the teammates enter as a set (exchanging two teammates' encodings and actions leaves critic i's
    output unchanged), and each critic keeps its own agent's reward (per-agent and competing rewards alike). The
    cost of an update grows as N for the networks and N^2 only for the attention's dot products. Where MAAC uses
    a soft actor-critic and shares one critic network between agents, this critic keeps MADDPG's deterministic
    actors and one quantile network per agent (or group) and network. Parameters as in ``QuantileCriticBase`` (its
    quantile MLPs read [h, ctx]; a group's agents share their own paths and quantile MLPs), and:

    :param embed_dim: the size E of the own path, the teammates' embeddings and the attention's output
    :param n_heads: attention heads (a divisor of ``embed_dim``)
    """

    def __init__(self, *args: Any, embed_dim: int = 64, n_heads: int = 4, **kwargs: Any) -> None:
        check_attention_arguments(embed_dim, n_heads)
        self.embed_dim, self.n_heads = int(embed_dim), int(n_heads)  # read by _build_networks
        super().__init__(*args, **kwargs)

    def _build_networks(self, net_arch: list[int], activation_fn: type[nn.Module], shared_by: tuple[int, ...] | None) -> None:
        features_dim, n_critics = self.features.features_dim, self.n_critics
        n_models = n_critics * self.n_agents
        self.activation = activation_fn()
        self.own_path = BatchedLinear(n_models, features_dim + self.action_dim, self.embed_dim, shared_by, own_bias=True)
        # One attention per network c, shared by the agents' critics
        self.teammate_embedding = BatchedLinear(n_critics, features_dim + self.action_dim, self.embed_dim)
        self.query = BatchedLinear(n_critics, features_dim, self.embed_dim)
        self.key = BatchedLinear(n_critics, self.embed_dim, self.embed_dim)
        self.value = BatchedLinear(n_critics, self.embed_dim, self.embed_dim)
        self.quantile_nets = BatchedMlp(n_models, 2 * self.embed_dim, self.n_outputs, net_arch, activation_fn, shared_by)

    def quantiles_from_features(self, features: th.Tensor, actions: th.Tensor) -> th.Tensor:
        actions = self._own_actions(actions)
        if actions.dim() == 3:
            return self._network_quantiles(features, actions.unsqueeze(1), actions, n_networks=1)[0]
        # critic i scores actions[:, i]: its own action is actions[:, i, i]
        own_actions = th.diagonal(actions, dim1=1, dim2=2).transpose(1, 2)  # (B, N, A)
        return self._network_quantiles(features, actions, own_actions, n_networks=1)[0]

    def all_quantiles_from_features(self, features: th.Tensor, actions: th.Tensor, shape_gradient: bool = True) -> th.Tensor:
        actions = self._own_actions(actions)
        return self._network_quantiles(features, actions.unsqueeze(1), actions, self.n_critics, shape_gradient)

    def quantiles_with_own_actions(self, features: th.Tensor, actions: th.Tensor, own_actions: th.Tensor) -> th.Tensor:
        """
        Critic i's teammates keep the batch's actions and only its own path reads ``own_actions[:, i]``: the
        attention over the teammates is computed once for all critics. Parameters as in ``QuantileCriticBase``.
        """
        actions, own_actions = self._own_actions(actions), self._own_actions(own_actions)
        return self._network_quantiles(features, actions.unsqueeze(1), own_actions, n_networks=1)[0]

    def _network_quantiles(
        self,
        features: th.Tensor,
        teammate_actions: th.Tensor,
        own_actions: th.Tensor,
        n_networks: int,
        shape_gradient: bool = True,
    ) -> th.Tensor:
        """
        The first ``n_networks`` networks of every agent's critic.

        :param features: (B, N, F)
        :param teammate_actions: the joint actions that the critics' attention reads, (B, 1, N, A) for one joint
            action seen by every critic, or (B, N, N, A) with ``[:, i]`` the one critic i reads
        :param own_actions: the action on each critic's own path, (B, N, A)
        :param n_networks: networks per agent to evaluate (1: the first; ``n_critics``: all)
        :param shape_gradient: see ``all_quantiles_from_features``
        :return: quantiles (n_networks, B, N, n_quantiles)
        """
        batch_size, n_agents = features.shape[:2]
        models = slice(0, n_networks * n_agents)
        own_input = th.cat([features, own_actions], dim=-1).transpose(0, 1)  # (N, B, F + A)
        own_input = own_input.unsqueeze(0).expand(n_networks, -1, -1, -1).reshape(n_networks * n_agents, batch_size, -1)
        own = self.activation(self.own_path.forward_model_major(own_input, models))  # (C * N, B, E)
        context = self._teammate_context(features, teammate_actions, n_networks)  # (C, B, N, E)
        context = context.transpose(1, 2).reshape(n_networks * n_agents, batch_size, -1)
        hidden = th.cat([own, context], dim=-1)
        quantiles = self._quantiles_from(hidden, start=0, models=models, shape_gradient=shape_gradient)
        return quantiles.view(n_networks, n_agents, batch_size, -1).transpose(1, 2)

    def _teammate_context(self, features: th.Tensor, teammate_actions: th.Tensor, n_networks: int) -> th.Tensor:
        """
        What each critic reads of its teammates: the attention's output (C, B, N, E), zero for a team of one.

        :param features: (B, N, F)
        :param teammate_actions: (B, I, N, A), I = 1 (shared) or N (one joint action per critic)
        :param n_networks: networks C per agent
        """
        batch_size, n_agents = features.shape[:2]
        n_joint = teammate_actions.shape[1]
        if n_agents == 1:
            return features.new_zeros(n_networks, batch_size, 1, self.embed_dim)
        networks = slice(0, n_networks)
        heads, head_dim = self.n_heads, self.embed_dim // self.n_heads
        # (C, B * I * N, F + A) -> embeddings e_j, keys and values (C, B * I * N, E)
        teammates = th.cat([features.unsqueeze(1).expand(-1, n_joint, -1, -1), teammate_actions], dim=-1)
        teammates = teammates.reshape(1, batch_size * n_joint * n_agents, -1).expand(n_networks, -1, -1)
        embedded = self.activation(self.teammate_embedding.forward_model_major(teammates, networks))

        keys = self.key.forward_model_major(embedded, networks)
        values = self.activation(self.value.forward_model_major(embedded, networks))
        queries = self.query.forward_model_major(
            features.reshape(1, batch_size * n_agents, -1).expand(n_networks, -1, -1), networks
        )
        # Each critic i attends to every agent j but itself (a boolean mask: True takes part)
        others = ~th.eye(n_agents, dtype=th.bool, device=features.device)
        if n_joint == 1:
            # One set of teammates for every critic: the N queries attend together, (C, B, heads, N, d)
            def by_head(x: th.Tensor) -> th.Tensor:
                return x.view(n_networks, batch_size, n_agents, heads, head_dim).transpose(2, 3)

            context = F.scaled_dot_product_attention(by_head(queries), by_head(keys), by_head(values), attn_mask=others)
            context = context.transpose(2, 3)  # (C, B, N, heads, d)
        else:
            # Critic i's own teammates: one query each, (C, B, N_i, heads, 1 or N_j, d)
            def by_critic(x: th.Tensor) -> th.Tensor:
                return x.view(n_networks, batch_size, n_agents, n_agents, heads, head_dim).transpose(3, 4)

            single_queries = queries.view(n_networks, batch_size, n_agents, heads, 1, head_dim)
            mask = others.view(n_agents, 1, 1, n_agents)
            context = F.scaled_dot_product_attention(single_queries, by_critic(keys), by_critic(values), attn_mask=mask)
        return context.reshape(n_networks, batch_size, n_agents, self.embed_dim)


def check_attention_arguments(embed_dim: Any, n_heads: Any) -> None:
    """The attention critic's own arguments: ``embed_dim`` and ``n_heads`` positive integers, heads dividing E."""
    check_int("embed_dim", embed_dim, low=1)
    check_int("n_heads", n_heads, low=1)
    if int(embed_dim) % int(n_heads) != 0:
        raise ValueError(f"the attention critic's embed_dim ({embed_dim}) must be a multiple of n_heads ({n_heads})")


# The critics a policy can be given (``critic=``), by name
CRITICS: dict[str, type[QuantileCriticBase]] = {"joint": MultiAgentQuantileCritic, "attention": AttentionQuantileCritic}
