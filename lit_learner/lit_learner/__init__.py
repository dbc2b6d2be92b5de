"""LIT* learner: the Fuzzy-DDPG policy for batch size B and neighbour factor psi_K.

:class:`~lit_learner.core.LearnerCore` takes :class:`~lit_learner.messages.DecisionRequest` and
:class:`~lit_learner.messages.EpisodeEnd` messages, returns executed actions, pairs transitions,
trains both agents at episode ends, checkpoints and exports lookup tensors. The specification is
``shared/design/LEARNER.md``.
"""

import sys as _sys

# The learner trains small networks on the CPU and never compiles them. Creating a torch optimizer
# imports torch._dynamo, which loads Triton, the GPU kernel compiler, when it is installed (the
# PyPI torch wheel brings it): about 35 ms at start-up, and at every exit its nanobind extension
# prints some thirty "nanobind: leaked ..." lines into the node's log. With None in sys.modules,
# `import triton` raises ImportError, which torch handles as "Triton is not installed".
if "triton" not in _sys.modules:
    _sys.modules["triton"] = None  # type: ignore[assignment]
