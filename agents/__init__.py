"""Reference policies (PD, the seed's heuristic, the optimal reference) and learned baselines."""

import warnings

import gymnasium  # noqa: F401  (its logger installs a DeprecationWarning filter; ours goes in front)

# The baselines train and compare on Scara-C11-v1 on purpose (scara_gym.TRAINING_ENV_ID), where
# Gymnasium would warn at every make that a -v2 exists.
warnings.filterwarnings("ignore", message=r".*Scara-C11-v1 is out of date", category=DeprecationWarning)
