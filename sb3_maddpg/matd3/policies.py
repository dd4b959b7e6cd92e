"""MATD3's policy: MADDPG's decentralised actors with twin centralised quantile critics per agent."""

from typing import Any

from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from sb3_maddpg.common.torch_layers import ReportCNN
from sb3_maddpg.maddpg.policies import MADDPGPolicy


class MATD3Policy(MADDPGPolicy):
    """
    ``MADDPGPolicy`` with ``n_critics=2`` by default: each agent's centralised critic has two quantile networks on
    the same encodings (TD3's twin critics, which SB3's ``TD3Policy`` also puts on one features extractor).
    Parameters as in ``MADDPGPolicy``.

    :param n_critics: quantile networks per agent's critic (2: twin critics)
    """

    def __init__(self, *args: Any, n_critics: int = 2, **kwargs: Any) -> None:
        super().__init__(*args, n_critics=n_critics, **kwargs)


MlpPolicy = MATD3Policy


class CnnPolicy(MATD3Policy):
    """
    MATD3 policy for image observations: ``MATD3Policy`` whose default features extractor is the report's CNN
    (``ReportCNN``). Parameters as in ``MADDPGPolicy``.

    :param features_extractor_class: the features extractor (``ReportCNN`` by default)
    """

    def __init__(self, *args: Any, features_extractor_class: type[BaseFeaturesExtractor] = ReportCNN, **kwargs: Any) -> None:
        super().__init__(*args, features_extractor_class=features_extractor_class, **kwargs)
