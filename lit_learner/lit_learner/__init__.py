"""LIT* learner: the Fuzzy-DDPG policy for batch size B and neighbour factor psi_K.

:class:`~lit_learner.core.LearnerCore` takes :class:`~lit_learner.messages.DecisionRequest` and
:class:`~lit_learner.messages.EpisodeEnd` messages, returns executed actions, pairs transitions,
trains both agents at episode ends, checkpoints and exports lookup tensors. The specification is
``shared/design/LEARNER.md``.
"""
