"""The MADDPG hyperparameter sampler for RL Zoo's Optuna search, in the style of ``rl_zoo3.hyperparams_opt``."""

from typing import Any

import optuna


def convert_maddpg_params(sampled_params: dict[str, Any]) -> dict[str, Any]:
    """
    Turn the values Optuna sampled into MADDPG arguments (also used to reload a trial with ``--trial-id``).

    :param sampled_params: the trial's parameters
    :return: keyword arguments of ``MADDPG``
    """
    hyperparams = sampled_params.copy()
    hyperparams["gamma"] = 1 - hyperparams.pop("one_minus_gamma")
    if "batch_size_pow" in hyperparams:
        hyperparams["batch_size"] = 2 ** hyperparams.pop("batch_size_pow")
    return hyperparams


def sample_maddpg_params(trial: optuna.Trial, n_actions: int, n_envs: int, additional_args: dict) -> dict[str, Any]:
    """
    Sampler for MADDPG hyperparameters.

    Only algorithm arguments are sampled: ``policy_kwargs`` (network sizes, ``n_quantiles``, the features extractor)
    stay as the YAML entry sets them, because RL Zoo replaces the whole ``policy_kwargs`` dict with a sampled one.
    The ranges are centred on the report's settings (gamma 0.83, lr 1e-3, batch 32, tau 0.01, train_freq 5,
    cvar_alpha 0.5).

    :param trial: the Optuna trial
    :param n_actions: size of one agent's action (unused: the exploration noise is MADDPG's decaying default)
    :param n_envs: number of environment copies
    :param additional_args: RL Zoo's extra arguments (HER settings, unused)
    :return: keyword arguments of ``MADDPG``
    """
    one_minus_gamma = trial.suggest_float("one_minus_gamma", 0.01, 0.3, log=True)
    # From 2**4 = 16 to 2**8 = 256 joint transitions
    batch_size_pow = trial.suggest_int("batch_size_pow", 4, 8)
    learning_rate = trial.suggest_float("learning_rate", 1e-4, 3e-3, log=True)
    tau = trial.suggest_float("tau", 0.001, 0.05, log=True)
    train_freq = trial.suggest_int("train_freq", 1, 10)
    cvar_alpha = trial.suggest_float("cvar_alpha", 0.1, 1.0)

    trial.set_user_attr("gamma", 1 - one_minus_gamma)
    trial.set_user_attr("batch_size", 2**batch_size_pow)

    return convert_maddpg_params(
        {
            "one_minus_gamma": one_minus_gamma,
            "batch_size_pow": batch_size_pow,
            "learning_rate": learning_rate,
            "tau": tau,
            "train_freq": train_freq,
            "cvar_alpha": cvar_alpha,
        }
    )
