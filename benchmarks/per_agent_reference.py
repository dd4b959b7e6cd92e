"""
A per-agent reference implementation of the MADDPG update, written the way typical MADDPG code (and the report's
code) is structured; it is NOT our library's implementation, and only serves as the baseline of a speed comparison
(``benchmarks/update_speed.py`` prints both).

    python benchmarks/per_agent_reference.py --device cpu --threads 1 --updates 3

Each agent i owns, in plain PyTorch and with no batching across agents:

- an actor mu_i: its own ReportCNN-structured encoder (Conv(C->16), Conv(16->32), Conv(32->64), 3x3 stride 2,
  padding 0, ReLU after each, BatchNorm2d(64), flatten) and an MLP [64, 64] -> action_dim with tanh;
- a centralised quantile critic Z_i with its OWN encoder for EVERY agent's observation (N encoders per critic, so
  N^2 encoder passes per evaluation of all critics), reading [f_1, ..., f_N, a_1, ..., a_N] through an MLP
  [64, 64] -> n_quantiles;
- target copies of both (kept in eval mode; soft-updated with tau, their BatchNorm running statistics copied).

One update loops over the agents, one after the other: critic i is trained with the quantile Huber loss
(kappa = 1, midpoints tau_j = (j + 0.5) / n, the plain formula) towards r_i + gamma (1 - d) Z_i'(o', a'),
a'_j = mu_j'(o'_j) from all target actors; then actor i is trained to maximise the mean of Z_i (CVaR with
alpha = 1) with a_i = mu_i(o_i) and the other actions from the batch. After the loop every target network is
soft-updated. Adam (lr 1e-3) for every network, gamma 0.95, tau 0.01, as in our library's defaults.

The batch is a set of random tensors of the right shapes, created once on the device: replay-buffer sampling is
not part of this reference and is not timed (our library's timing in ``update_speed.py`` includes its sampling).
"""

import argparse
import time
from dataclasses import dataclass

import torch as th
from torch import nn

ACTION_DIM = 2
N_CHANNELS = 3
NET_ARCH = (64, 64)
GAMMA = 0.95
TAU = 0.01
LEARNING_RATE = 1e-3


class ReportEncoder(nn.Module):
    """
    The report's CNN for one observation: three 3x3 stride-2 convolutions (16, 32, 64 channels, padding 0) with ReLU,
    BatchNorm2d(64) and flatten. uint8 images are divided by 255 inside.

    :param n_channels: input channels C
    :param image_size: height and width S of the square images
    """

    def __init__(self, n_channels: int, image_size: int) -> None:
        super().__init__()
        self.cnn = nn.Sequential(
            nn.Conv2d(n_channels, 16, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.Conv2d(16, 32, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.Conv2d(32, 64, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.BatchNorm2d(64),
            nn.Flatten(),
        )
        side = image_size
        for _ in range(3):
            side = (side - 3) // 2 + 1
        self.features_dim = 64 * side * side

    def forward(self, images: th.Tensor) -> th.Tensor:
        """
        :param images: (B, C, S, S) uint8
        :return: features (B, features_dim)
        """
        return self.cnn(images.float() / 255.0)


def mlp(input_dim: int, output_dim: int, net_arch: tuple[int, ...] = NET_ARCH) -> nn.Sequential:
    """
    :param input_dim: input size
    :param output_dim: output size
    :param net_arch: hidden layer sizes, ReLU after each
    :return: the MLP, with no activation on the output
    """
    layers: list[nn.Module] = []
    sizes = [input_dim, *net_arch]
    for in_size, out_size in zip(sizes[:-1], sizes[1:], strict=True):
        layers += [nn.Linear(in_size, out_size), nn.ReLU()]
    layers.append(nn.Linear(sizes[-1], output_dim))
    return nn.Sequential(*layers)


class Actor(nn.Module):
    """
    mu_i(o_i): agent i's own encoder, an MLP and tanh.

    :param n_channels: image channels
    :param image_size: image side
    :param action_dim: action size
    """

    def __init__(self, n_channels: int, image_size: int, action_dim: int) -> None:
        super().__init__()
        self.encoder = ReportEncoder(n_channels, image_size)
        self.mu = mlp(self.encoder.features_dim, action_dim)

    def forward(self, observation: th.Tensor) -> th.Tensor:
        """
        :param observation: agent i's images (B, C, S, S) uint8
        :return: actions in [-1, 1], (B, action_dim)
        """
        return th.tanh(self.mu(self.encoder(observation)))


class Critic(nn.Module):
    """
    Z_i(o, a): a centralised quantile critic owning one encoder per agent's observation.

    :param n_agents: number of agents N
    :param n_channels: image channels
    :param image_size: image side
    :param action_dim: action size of each agent
    :param n_quantiles: number of output quantiles
    """

    def __init__(self, n_agents: int, n_channels: int, image_size: int, action_dim: int, n_quantiles: int) -> None:
        super().__init__()
        self.encoders = nn.ModuleList(ReportEncoder(n_channels, image_size) for _ in range(n_agents))
        input_dim = n_agents * (self.encoders[0].features_dim + action_dim)
        self.quantiles = mlp(input_dim, n_quantiles)

    def forward(self, observations: list[th.Tensor], actions: list[th.Tensor]) -> th.Tensor:
        """
        :param observations: the N agents' images, each (B, C, S, S) uint8
        :param actions: the N agents' actions, each (B, action_dim)
        :return: quantiles (B, n_quantiles)
        """
        features = [encoder(obs) for encoder, obs in zip(self.encoders, observations, strict=True)]
        return self.quantiles(th.cat([*features, *actions], dim=1))


def quantile_huber_loss(current: th.Tensor, target: th.Tensor, kappa: float = 1.0) -> th.Tensor:
    """
    QR-DQN's quantile Huber loss, the plain formula: sum_j mean_k |tau_j - 1{delta_jk < 0}| huber_kappa(delta_jk) / kappa
    with delta_jk = t_k - z_j and tau_j = (j + 0.5) / n, averaged over the batch.

    :param current: the critic's quantiles z, (B, n)
    :param target: the target samples t (constants), (B, m)
    :param kappa: Huber threshold
    :return: scalar loss
    """
    n_quantiles = current.shape[1]
    taus = (th.arange(n_quantiles, device=current.device, dtype=current.dtype) + 0.5) / n_quantiles
    delta = target.unsqueeze(1) - current.unsqueeze(2)  # (B, n, m)
    abs_delta = delta.abs()
    huber = th.where(abs_delta <= kappa, 0.5 * delta.pow(2), kappa * (abs_delta - 0.5 * kappa))
    weight = (taus.view(1, -1, 1) - (delta.detach() < 0).float()).abs()
    return (weight * huber / kappa).mean(dim=2).sum(dim=1).mean()


@dataclass
class Agent:
    """One agent's networks, their targets and optimizers."""

    actor: Actor
    critic: Critic
    actor_target: Actor
    critic_target: Critic
    actor_optimizer: th.optim.Adam
    critic_optimizer: th.optim.Adam


@dataclass
class Batch:
    """A batch of B joint transitions: per-agent lists of tensors, as per-agent MADDPG code keeps them."""

    observations: list[th.Tensor]  # N x (B, C, S, S) uint8
    actions: list[th.Tensor]  # N x (B, A) in [-1, 1]
    rewards: list[th.Tensor]  # N x (B, 1)
    next_observations: list[th.Tensor]  # N x (B, C, S, S) uint8
    dones: th.Tensor  # (B, 1)


def make_agents(
    n_agents: int, n_quantiles: int, image_size: int, device: th.device | str, action_dim: int = ACTION_DIM
) -> list[Agent]:
    """
    :param n_agents: number of agents N
    :param n_quantiles: quantiles per critic
    :param image_size: image side S
    :param device: device of the networks
    :param action_dim: action size of each agent
    :return: the N agents, targets initialised as copies and in eval mode
    """
    agents = []
    for _ in range(n_agents):
        actor = Actor(N_CHANNELS, image_size, action_dim).to(device)
        critic = Critic(n_agents, N_CHANNELS, image_size, action_dim, n_quantiles).to(device)
        actor_target = Actor(N_CHANNELS, image_size, action_dim).to(device)
        critic_target = Critic(n_agents, N_CHANNELS, image_size, action_dim, n_quantiles).to(device)
        actor_target.load_state_dict(actor.state_dict())
        critic_target.load_state_dict(critic.state_dict())
        actor_target.eval()
        critic_target.eval()
        agents.append(
            Agent(
                actor,
                critic,
                actor_target,
                critic_target,
                th.optim.Adam(actor.parameters(), lr=LEARNING_RATE),
                th.optim.Adam(critic.parameters(), lr=LEARNING_RATE),
            )
        )
    return agents


def random_batch(
    n_agents: int, batch_size: int, image_size: int, device: th.device | str, action_dim: int = ACTION_DIM
) -> Batch:
    """
    :param n_agents: number of agents N
    :param batch_size: joint transitions B
    :param image_size: image side S
    :param device: where the tensors are created
    :param action_dim: action size of each agent
    :return: random uint8 images, actions in [-1, 1], normal rewards and a few terminations
    """
    shape = (batch_size, N_CHANNELS, image_size, image_size)

    def images() -> list[th.Tensor]:
        return [th.randint(0, 256, shape, dtype=th.uint8, device=device) for _ in range(n_agents)]

    return Batch(
        observations=images(),
        actions=[th.rand(batch_size, action_dim, device=device) * 2 - 1 for _ in range(n_agents)],
        rewards=[th.randn(batch_size, 1, device=device) for _ in range(n_agents)],
        next_observations=images(),
        dones=(th.rand(batch_size, 1, device=device) < 0.02).float(),
    )


@th.no_grad()
def soft_update(source: nn.Module, target: nn.Module, tau: float = TAU) -> None:
    """
    target <- tau * source + (1 - tau) * target for the parameters; the buffers (BatchNorm running statistics) are copied.

    :param source: the trained network
    :param target: its target copy
    :param tau: soft update coefficient
    """
    for param, target_param in zip(source.parameters(), target.parameters(), strict=True):
        target_param.mul_(1.0 - tau).add_(param, alpha=tau)
    for buffer, target_buffer in zip(source.buffers(), target.buffers(), strict=True):
        target_buffer.copy_(buffer)


def update(agents: list[Agent], batch: Batch) -> dict[str, list[float]]:
    """
    One full MADDPG update: for each agent in turn, a critic step and an actor step; then soft target updates.

    :param agents: the N agents (modified in place)
    :param batch: the batch of joint transitions
    :return: ``critic_loss`` and ``actor_loss`` of each agent
    """
    critic_losses: list[th.Tensor] = []
    actor_losses: list[th.Tensor] = []
    for i, agent in enumerate(agents):
        agent.actor.train()
        agent.critic.train()

        # Critic i: quantile regression towards r_i + gamma (1 - d) Z_i'(o', a'), a'_j = mu_j'(o'_j)
        with th.no_grad():
            next_actions = [other.actor_target(obs) for other, obs in zip(agents, batch.next_observations, strict=True)]
            next_quantiles = agent.critic_target(batch.next_observations, next_actions)
            target = batch.rewards[i] + GAMMA * (1.0 - batch.dones) * next_quantiles
        current = agent.critic(batch.observations, batch.actions)
        critic_loss = quantile_huber_loss(current, target)
        agent.critic_optimizer.zero_grad()
        critic_loss.backward()
        agent.critic_optimizer.step()

        # Actor i: maximise the mean of Z_i (CVaR with alpha = 1), a_i = mu_i(o_i), the other actions from the batch
        actions = list(batch.actions)
        actions[i] = agent.actor(batch.observations[i])
        actor_loss = -agent.critic(batch.observations, actions).mean()
        agent.actor_optimizer.zero_grad()
        actor_loss.backward()
        agent.actor_optimizer.step()

        critic_losses.append(critic_loss.detach())
        actor_losses.append(actor_loss.detach())

    for agent in agents:
        soft_update(agent.critic, agent.critic_target)
        soft_update(agent.actor, agent.actor_target)
    return {
        "critic_loss": [float(loss) for loss in critic_losses],
        "actor_loss": [float(loss) for loss in actor_losses],
    }


def ms_per_update(
    n_agents: int,
    batch_size: int,
    n_quantiles: int,
    image_size: int,
    device: th.device | str,
    n_updates: int,
    warmup: int = 3,
) -> float:
    """
    Milliseconds per reference update (sampling excluded: one random batch on the device is reused).

    :param n_agents: number of agents N
    :param batch_size: joint transitions per update
    :param n_quantiles: quantiles per critic
    :param image_size: image side S (3 x S x S uint8 images)
    :param device: "cpu" or "cuda"
    :param n_updates: timed updates
    :param warmup: untimed updates first
    :return: mean wall-clock milliseconds per update
    """
    device = th.device(device)
    th.manual_seed(0)
    agents = make_agents(n_agents, n_quantiles, image_size, device)
    batch = random_batch(n_agents, batch_size, image_size, device)
    sync = th.cuda.synchronize if device.type == "cuda" else (lambda: None)
    for _ in range(warmup):
        update(agents, batch)
    sync()
    start = time.perf_counter()
    for _ in range(n_updates):
        update(agents, batch)
    sync()
    return (time.perf_counter() - start) / n_updates * 1e3


CONFIGURATIONS = ((6, 32), (4, 256))  # (agents, batch) of the report and of a larger batch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cuda" if th.cuda.is_available() else "cpu", help="torch device")
    parser.add_argument("--threads", type=int, default=None, help="torch intra-op threads on CPU (default: torch's)")
    parser.add_argument("--updates", type=int, default=10, help="timed updates per configuration")
    parser.add_argument("--warmup", type=int, default=1, help="untimed updates first")
    parser.add_argument("--quantiles", type=int, default=50, help="quantiles per critic")
    parser.add_argument("--image-size", type=int, default=80, help="image side S (images are 3 x S x S)")
    args = parser.parse_args()
    if args.threads is not None:
        th.set_num_threads(args.threads)

    print(f"per-agent reference update on {args.device}, torch {th.__version__}, CPU threads {th.get_num_threads()}")
    print()
    print("| agents | batch | quantiles | image | ms per update |")
    print("|---|---|---|---|---|")
    for n_agents, batch_size in CONFIGURATIONS:
        ms = ms_per_update(n_agents, batch_size, args.quantiles, args.image_size, args.device, args.updates, args.warmup)
        image = f"{N_CHANNELS}x{args.image_size}x{args.image_size}"
        print(f"| {n_agents} | {batch_size} | {args.quantiles} | {image} | {ms:.1f} |", flush=True)


if __name__ == "__main__":
    main()
