"""Test-wide settings."""

import torch as th

# The networks in the tests are tiny: one intra-op thread is faster than several, and keeps runs reproducible
# and independent of how busy the machine is.
th.set_num_threads(1)
