"""Network building blocks: the report's CNN, per-agent encoders and agent-stacked MLPs.

Multi-agent tensors are batch-first with the agent dimension second: observations (B, N, *obs_shape),
features (B, N, F), actions (B, N, A). "Stacked" modules hold N independent networks and evaluate all of them
in one call (grouped convolutions, batched matrix products), so the number of kernel launches does not grow with N.
"""

import math
from typing import Any, ClassVar

import torch as th
from gymnasium import spaces
from stable_baselines3.common.preprocessing import preprocess_obs
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn


class ReportCNN(BaseFeaturesExtractor):
    """
    The report's encoder: Conv(C->16), Conv(16->32), Conv(32->64), each 3x3 with stride 2 and no padding (by default),
    each followed by ReLU, then BatchNorm over the 64 channels, then flatten (other widths with ``channels``).
    The flatten size comes from one dummy forward pass (64 * 9 * 9 = 5184 for 80x80 inputs, 64 for 16x16).

    With ``n_agents > 1`` the module holds ``n_agents`` independent copies of this encoder as grouped
    convolutions (``groups=n_agents``) and a BatchNorm over ``n_agents * 64`` channels: every copy has its own weights
    and its own running statistics, exactly as separate modules would, but all agents are encoded in one pass.

    :param observation_space: a channel-first Box of shape (C, H, W) with H, W >= 15
    :param n_agents: number of independent encoders evaluated together; input (B, n_agents, C, H, W) when > 1
    :param normalized_image: accepted for compatibility with SB3's image extractors; unused
        (images are scaled to [0, 1] before the extractor when ``normalize_images=True``)
    :param padding: zero padding of each convolution. The report's 0 leaves pixels unread: at 16x16 the three
        convolutions read pixels 0-14 only, so the last row and column (31 of 256 map cells) reach no feature,
        and at 80x80 the last row and column. ``padding=1`` reads every pixel
    :param coord_channels: append two constant channels holding each pixel's column and row in [0, 1] to the input
        (CoordConv, Liu et al. 2018, https://arxiv.org/abs/1807.03247), so that the encoder can tell where on the map
        a pattern lies (the UAV's own position, the walls), not only what it looks like
    :param batch_norm_eps: the BatchNorm's epsilon (PyTorch's default). A replay buffer of near-identical images
        (a team that stays still) drives the running variances towards 0; the target networks, in eval mode, then
        divide small drifts by sqrt(eps) (316x at 1e-5) and their TD targets can diverge. A larger value (1e-3)
        bounds this, through ``policy_kwargs=dict(features_extractor_kwargs=dict(batch_norm_eps=1e-3))``
    :param position_channel: index of an input channel that marks one object (the UAV's own cell, channel 1 of the
        UAV env), or None. When set, three numbers are appended to the features: the channel's centre of mass
        (column, row in [0, 1], 0 where the channel is empty) and its maximum (the UAV env's energy level; with the
        env's ``position_mark="exact"`` the centre of mass is the exact position and the maximum is the energy level
        times the largest share of a pixel the mark covers, between 1/4 and 1 at one pixel per cell). The
        networks then get the position exactly, where otherwise they must decode it from three stride-2 convolutions
    :param channels: output channels of the three convolutions: the report's (16, 32, 64) by default, sized for its
        80 x 80 images. At one pixel per cell (16 x 16 inputs, 2 x 2 pixels after the third convolution) (8, 16, 32)
        costs a third of the arithmetic and gives the critics half as many inputs (docs/benchmarks.md)
    """

    stacks_agents: ClassVar[bool] = True

    def __init__(
        self,
        observation_space: spaces.Box,
        n_agents: int = 1,
        normalized_image: bool = False,
        padding: int = 0,
        coord_channels: bool = False,
        batch_norm_eps: float = 1e-5,
        position_channel: int | None = None,
        channels: tuple[int, int, int] = (16, 32, 64),
    ) -> None:
        if not isinstance(observation_space, spaces.Box) or len(observation_space.shape) != 3:
            raise ValueError(
                "ReportCNN accepts a channel-first image Box of shape (C, H, W), "
                f"got {observation_space}; use MlpPolicy for vector observations"
            )
        n_channels, height, width = observation_space.shape
        if min(height, width) < 15:
            raise ValueError(
                f"ReportCNN needs images of at least 15x15 pixels (three 3x3 stride-2 convolutions), got {height}x{width}"
            )
        if isinstance(batch_norm_eps, bool) or not isinstance(batch_norm_eps, int | float) or not batch_norm_eps > 0:
            raise ValueError(f"batch_norm_eps must be a number > 0, got {batch_norm_eps!r}")
        if isinstance(padding, bool) or not isinstance(padding, int) or padding not in (0, 1):
            raise ValueError(f"padding must be 0 (the report's) or 1 (every pixel read), got {padding!r}")
        if not isinstance(coord_channels, bool):
            raise TypeError(f"coord_channels must be True or False, got {coord_channels!r}")
        if (
            not isinstance(channels, tuple | list)
            or len(channels) != 3
            or not all(isinstance(c, int) and not isinstance(c, bool) and c >= 1 for c in channels)
        ):
            raise ValueError(f"channels must be three integers >= 1 (the convolutions' widths), got {channels!r}")
        if position_channel is not None and (
            isinstance(position_channel, bool)
            or not isinstance(position_channel, int)
            or not 0 <= position_channel < n_channels
        ):
            raise ValueError(
                f"position_channel must be None or a channel index in [0, {n_channels - 1}], got {position_channel!r}"
            )
        super().__init__(observation_space, features_dim=1)
        self.n_agents = n_agents
        self.position_channel = position_channel
        self.coord_channels = coord_channels
        g = n_agents
        in_channels = n_channels + (2 if coord_channels else 0)
        if coord_channels:
            rows = th.linspace(0.0, 1.0, height).view(1, height, 1).expand(1, height, width)
            cols = th.linspace(0.0, 1.0, width).view(1, 1, width).expand(1, height, width)
            self.register_buffer("coords", th.cat([cols, rows]).contiguous(), persistent=False)
        c1, c2, c3 = channels
        self.cnn = nn.Sequential(
            nn.Conv2d(g * in_channels, g * c1, kernel_size=3, stride=2, padding=padding, groups=g),
            nn.ReLU(),
            nn.Conv2d(g * c1, g * c2, kernel_size=3, stride=2, padding=padding, groups=g),
            nn.ReLU(),
            nn.Conv2d(g * c2, g * c3, kernel_size=3, stride=2, padding=padding, groups=g),
            nn.ReLU(),
            nn.BatchNorm2d(g * c3, eps=batch_norm_eps),
        )
        # Flatten size per agent from one dummy pass (eval mode so the running statistics stay untouched)
        self.cnn.eval()
        with th.no_grad():
            dummy = th.zeros(1, g * in_channels, height, width)
            self._features_dim = self.cnn(dummy).numel() // g
        self.cnn.train()
        if position_channel is not None:
            self.register_buffer("pixel_cols", th.linspace(0.0, 1.0, width), persistent=False)
            self.register_buffer("pixel_rows", th.linspace(0.0, 1.0, height), persistent=False)
            self._features_dim += 3

    def _position_features(self, observations: th.Tensor) -> th.Tensor:
        """(..., C, H, W) images -> (..., 3): centre of mass (column, row) and maximum of ``position_channel``."""
        marked = observations[..., self.position_channel, :, :]  # (..., H, W)
        by_col, by_row = marked.sum(dim=-2), marked.sum(dim=-1)  # (..., W), (..., H)
        mass = by_col.sum(dim=-1, keepdim=True)
        # An empty channel (a depleted UAV) gives position 0 instead of 0 / 0
        scale = th.where(mass > 0, mass, th.ones_like(mass)).reciprocal()
        col = (by_col @ self.pixel_cols.to(marked.dtype)).unsqueeze(-1) * scale
        row = (by_row @ self.pixel_rows.to(marked.dtype)).unsqueeze(-1) * scale
        peak = marked.flatten(-2).amax(dim=-1, keepdim=True)
        return th.cat([col, row, peak], dim=-1)

    def _with_coords(self, observations: th.Tensor) -> th.Tensor:
        """Append the coordinate channels to (..., C, H, W) images."""
        coords = self.coords.to(observations.dtype).expand(*observations.shape[:-3], *self.coords.shape)
        return th.cat([observations, coords], dim=-3)

    def forward(self, observations: th.Tensor) -> th.Tensor:
        """
        :param observations: (B, C, H, W) when ``n_agents == 1``, otherwise (B, n_agents, C, H, W)
        :return: features (B, F) when ``n_agents == 1`` and the input is 4-D, otherwise (B, n_agents, F)
        """
        positions = self._position_features(observations) if self.position_channel is not None else None
        if self.coord_channels:
            observations = self._with_coords(observations)
        if observations.dim() == 4:
            features = self._encode(observations).flatten(1)
        else:
            batch_size = observations.shape[0]
            # (B, N, C, H, W) -> (B, N*C, H, W): group g of the convolutions reads agent g's channels
            features = self._encode(observations.flatten(1, 2)).reshape(batch_size, self.n_agents, -1)
        if positions is not None:
            features = th.cat([features, positions.to(features.dtype)], dim=-1)
        return features

    def _encode(self, images: th.Tensor) -> th.Tensor:
        # Channels-last halves the time of the grouped convolutions on CPU (oneDNN); the output goes back to the
        # default layout so that flatten keeps the (C, H, W) order of the features.
        if images.device.type == "cpu":
            images = images.contiguous(memory_format=th.channels_last)
        return self.cnn(images).contiguous()


class MultiAgentFeatures(nn.Module):
    """
    Encodes every agent's observation with that agent's features extractor: (B, N, *obs) -> (B, N, F).

    How the N extractors are held depends on the extractor class:

    - ``shared=True``: one extractor applied to all agents (the batch and agent dimensions are folded together);
    - an extractor class with ``stacks_agents = True`` (such as ``ReportCNN``): one module built with
      ``n_agents=N`` that encodes all agents in one pass;
    - a stateless extractor (no parameters or buffers, e.g. ``FlattenExtractor``): one instance shared, as copies
      would be identical;
    - any other ``BaseFeaturesExtractor``: N instances called in a loop over agents (still N passes, not N^2).

    Observations are preprocessed as in SB3 (images divided by 255 when ``normalize_images``).

    :param observation_space: one agent's observation space
    :param n_agents: number of agents N
    :param features_extractor_class: SB3 features extractor class
    :param features_extractor_kwargs: keyword arguments of the extractor
    :param normalize_images: whether to divide image observations by 255
    :param shared: one extractor for all agents
    :param observation_mask: (N, *obs_shape) booleans marking each agent's own entries of padded observations (agents
        with spaces of their own); the others are set to 0 before any extractor reads them. None: nothing is padded
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        n_agents: int,
        features_extractor_class: type[BaseFeaturesExtractor],
        features_extractor_kwargs: dict[str, Any] | None = None,
        normalize_images: bool = True,
        shared: bool = False,
        observation_mask: th.Tensor | None = None,
    ) -> None:
        super().__init__()
        self.observation_mask: th.Tensor | None
        self.register_buffer("observation_mask", observation_mask, persistent=False)
        kwargs = features_extractor_kwargs or {}
        self.observation_space = observation_space
        self.n_agents = n_agents
        self.normalize_images = normalize_images
        self.extractors = nn.ModuleList()
        if shared:
            self.mode = "shared"
            self.extractors.append(features_extractor_class(observation_space, **kwargs))
        elif getattr(features_extractor_class, "stacks_agents", False):
            self.mode = "stacked"
            self.extractors.append(features_extractor_class(observation_space, n_agents=n_agents, **kwargs))
        else:
            first = features_extractor_class(observation_space, **kwargs)
            stateless = not any(True for _ in first.parameters()) and not any(True for _ in first.buffers())
            self.mode = "shared" if stateless else "loop"
            self.extractors.append(first)
            if not stateless:
                self.extractors.extend(features_extractor_class(observation_space, **kwargs) for _ in range(n_agents - 1))
        self.features_dim: int = self.extractors[0].features_dim

    def forward(self, observations: th.Tensor) -> th.Tensor:
        """
        :param observations: (B, N, *obs_shape), raw (e.g. uint8 images)
        :return: features (B, N, F)
        """
        if self.observation_mask is not None:
            # Padding is a constant 0, not data: it moves no feature and trains no weight
            observations = observations.masked_fill(~self.observation_mask, 0)
        obs = preprocess_obs(observations, self.observation_space, normalize_images=self.normalize_images)
        assert isinstance(obs, th.Tensor)
        batch_size, n_agents = obs.shape[:2]
        if self.mode == "shared":
            return self.extractors[0](obs.flatten(0, 1)).view(batch_size, n_agents, -1)
        if self.mode == "stacked":
            return self.extractors[0](obs)
        return th.stack([extractor(obs[:, i]) for i, extractor in enumerate(self.extractors)], dim=1)


class BatchedLinear(nn.Module):
    """
    ``n_models`` independent linear layers evaluated with one batched matrix product:
    (B, n_models, in_features) -> (B, n_models, out_features). Each model is initialised like ``nn.Linear``.

    With ``shared_by`` the models share weights: model m uses weight row ``shared_by[m]`` (parameter sharing inside
    groups of agents), and, with ``own_bias``, a bias of its own, which is what a one-hot model-index input would add
    to a shared first layer (an agent-index input); without it the bias is shared as well.

    :param n_models: number of layers evaluated (models)
    :param in_features: input size
    :param out_features: output size
    :param shared_by: for each model, the index of the weight it uses (0 .. number of distinct weights - 1); None:
        every model its own
    :param own_bias: with ``shared_by``, each model keeps a bias of its own
    """

    def __init__(
        self,
        n_models: int,
        in_features: int,
        out_features: int,
        shared_by: tuple[int, ...] | None = None,
        own_bias: bool = False,
    ) -> None:
        super().__init__()
        self.n_models = n_models
        self.in_features = in_features
        self.out_features = out_features
        n_weights = n_models if shared_by is None else max(shared_by) + 1
        self.model_index: th.Tensor | None
        self.bias_index: th.Tensor | None
        if shared_by is not None:
            if len(shared_by) != n_models or set(shared_by) != set(range(n_weights)):
                raise ValueError(
                    f"shared_by must give each of the {n_models} models a weight index 0, 1, ..., got {shared_by}"
                )
            self.register_buffer("model_index", th.as_tensor(shared_by, dtype=th.long), persistent=False)
        else:
            self.register_buffer("model_index", None, persistent=False)
            own_bias = True
        self.register_buffer("bias_index", None if own_bias else self.model_index, persistent=False)
        self.weight = nn.Parameter(th.empty(n_weights, in_features, out_features))
        self.bias = nn.Parameter(th.empty(n_models if own_bias else n_weights, out_features))
        # nn.Linear's default initialisation, U(-1/sqrt(fan_in), 1/sqrt(fan_in)), for weights and biases
        bound = 1.0 / math.sqrt(in_features) if in_features > 0 else 0.0
        nn.init.uniform_(self.weight, -bound, bound)
        nn.init.uniform_(self.bias, -bound, bound)

    def weights(self) -> tuple[th.Tensor, th.Tensor]:
        """Each model's weight (n_models, in, out) and bias (n_models, out): views of shared ones are gathered."""
        weight = self.weight if self.model_index is None else self.weight.index_select(0, self.model_index)
        bias = self.bias if self.bias_index is None else self.bias.index_select(0, self.bias_index)
        return weight, bias

    def forward(self, x: th.Tensor) -> th.Tensor:
        """
        :param x: (B, n_models, in_features)
        :return: (B, n_models, out_features)
        """
        return self.forward_model_major(x.transpose(0, 1)).transpose(0, 1)

    def forward_model_major(self, x: th.Tensor, models: slice | None = None) -> th.Tensor:
        """
        The same layer on model-major inputs, the layout of the batched product (no transposes).

        :param x: (M, B, in_features), M the number of models evaluated
        :param models: the models to evaluate (all when None)
        :return: (M, B, out_features)
        """
        weight, bias = self.weights()
        if models is not None:
            weight, bias = weight[models], bias[models]
        # (M, B, in) @ (M, in, out) + (M, 1, out) -> (M, B, out)
        return th.baddbmm(bias.unsqueeze(1), x, weight)

    def forward_with_block_changes(
        self, x: th.Tensor, changes: th.Tensor, start: int, models: slice | None = None
    ) -> th.Tensor:
        """
        Model m on the shared input ``x`` in which only the block of input features
        ``[start + m * k, start + (m + 1) * k)`` is moved by ``changes[m]`` (k = ``changes.shape[-1]``), without
        building the M changed inputs: the layer is linear, so the output is model m's output on ``x`` plus
        ``changes[m]`` times the k rows of model m's weight that read that block.

        :param x: the shared input, (B, in_features)
        :param changes: (M, B, k), one block change per evaluated model
        :param start: index of model 0's block in the input
        :param models: the models to evaluate (all when None); their number must be ``changes.shape[0]``
        :return: (M, B, out_features)
        """
        n_models, block = changes.shape[0], changes.shape[-1]
        weight = self.weights()[0]
        weight = weight if models is None else weight[models]
        shared = self.forward_model_major(x.unsqueeze(0).expand(n_models, -1, -1), models)
        # own_rows[m] = the rows of model m's weight that read block m, (M, k, out); a strided view
        block_rows = weight[:, start : start + n_models * block].view(n_models, n_models, block, -1)
        own_rows = th.diagonal(block_rows, dim1=0, dim2=1).permute(2, 0, 1)
        return th.baddbmm(shared, changes, own_rows)

    def extra_repr(self) -> str:
        shared = "" if self.model_index is None else f", shared weights={self.weight.shape[0]}"
        return f"n_models={self.n_models}, in_features={self.in_features}, out_features={self.out_features}{shared}"


class BatchedMlp(nn.Module):
    """
    ``n_models`` independent MLPs (hidden layers ``net_arch``, ``activation_fn`` between layers, optional tanh at
    the end) evaluated together: (B, n_models, input_dim) -> (B, n_models, output_dim).
    With ``n_models=1`` and an input of shape (B, M, input_dim), M > 1, the single MLP is applied to all M slots.

    :param n_models: number of independent MLPs
    :param input_dim: input size
    :param output_dim: output size
    :param net_arch: hidden layer sizes
    :param activation_fn: activation between layers
    :param squash_output: apply tanh to the output
    :param shared_by: models that share their weights (``BatchedLinear``'s): model m uses the weights of index
        ``shared_by[m]`` in every layer, and a first-layer bias of its own (an agent-index input); None: all models
        independent
    """

    def __init__(
        self,
        n_models: int,
        input_dim: int,
        output_dim: int,
        net_arch: list[int],
        activation_fn: type[nn.Module] = nn.ReLU,
        squash_output: bool = False,
        shared_by: tuple[int, ...] | None = None,
    ) -> None:
        super().__init__()
        self.n_models = n_models
        layers: list[nn.Module] = []
        sizes = [input_dim, *net_arch]
        for index, (in_size, out_size) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
            layers += [BatchedLinear(n_models, in_size, out_size, shared_by, own_bias=index == 0), activation_fn()]
        layers.append(BatchedLinear(n_models, sizes[-1], output_dim, shared_by, own_bias=not net_arch))
        if squash_output:
            layers.append(nn.Tanh())
        self.net = nn.Sequential(*layers)

    def forward(self, x: th.Tensor) -> th.Tensor:
        """
        :param x: (B, n_models, input_dim), or (B, M, input_dim) when ``n_models == 1``
        :return: (B, n_models or M, output_dim)
        """
        batch_size, n_slots = x.shape[:2]
        if self.n_models == 1 and n_slots != 1:
            # one model for all slots: the slots join the batch, (1, B * M, input_dim)
            return self._model_major(x.reshape(1, batch_size * n_slots, -1)).view(batch_size, n_slots, -1)
        # The hidden activations stay model-major, (n_models, B, width): one transpose in, one out
        return self._model_major(x.transpose(0, 1)).transpose(0, 1)

    def _model_major(self, x: th.Tensor) -> th.Tensor:
        return self.model_major_from(x, start=0)

    def model_major_from(self, x: th.Tensor, start: int, models: slice | None = None, stop: int | None = None) -> th.Tensor:
        """
        The layers ``net[start:stop]`` on model-major inputs (a caller that computes the first layer its own way
        continues here with ``start=1``).

        :param x: (M, B, width) input of layer ``start``
        :param start: index of the first layer to apply
        :param models: the models to evaluate (all when None), M of them
        :param stop: index of the layer to stop before (None: through the output)
        :return: (M, B, output_dim), or the input of layer ``stop``
        """
        for layer in self.net[start:stop]:
            x = layer.forward_model_major(x, models) if isinstance(layer, BatchedLinear) else layer(x)
        return x

    @property
    def first_layer(self) -> BatchedLinear:
        """The first linear layer (callers that share its input between models compute it their own way)."""
        first = self.net[0]
        assert isinstance(first, BatchedLinear)
        return first
