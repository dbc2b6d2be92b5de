"""LIT* learner package.

The Fuzzy-DDPG learner (B and psi_K agents, prioritized replay, rewards, tensor export and the
learner node) arrives with its issue; this module only reserves the package.
"""
