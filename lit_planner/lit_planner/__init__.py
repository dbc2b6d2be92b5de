"""LIT* planner: Python side of the planner (bindings, node, CLI, scenario registry)."""
