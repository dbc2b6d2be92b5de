"""The learner node answers decisions while its core's lock is taken (a checkpoint copies the
state under it for tens of ms) and records them afterwards, in order; time order is still checked
against decisions not recorded yet, and an episode end records its episode's decisions first.

The node runs in a child process of its own (rclpy's global state stays out of pytest's), in a
ROS domain of its own; its decide callback is called directly, as its serving thread would.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

from ros_helpers import run_node_script

SCRIPT = textwrap.dedent(
    """
    import json, sys
    import rclpy
    from diagnostic_msgs.srv import AddDiagnostics
    from lit_msgs_json.envelope import Publisher, decode

    folder = sys.argv[1]
    rclpy.init(args=["--ros-args", "-p", f"checkpoint:={folder}/c.pt",
                     "-p", f"export_dir:={folder}/tensors", "-p", "checkpoint_period:=3600.0"])
    from lit_learner.node import LearnerNode

    learner = LearnerNode()
    warnings = []
    warn = learner.log.warning
    learner.log.warning = lambda text, *args, **kwargs: (warnings.append(text),
                                                         warn(text, *args, **kwargs))
    publisher = Publisher("planner/test", "run-1")
    key = "planner/test|run-1|e1"

    def call(name, payload, sender=publisher):
        request = AddDiagnostics.Request()
        request.load_namespace = sender.encode(name, payload)
        response = learner._serve(request, AddDiagnostics.Response())
        learner._decide._run_deferred("test")  # as the serving thread does after the answer
        return bool(response.success), decode(response.message).payload

    def decide(agent, t):
        return {"agent": agent, "episode_id": "e1", "rho_global": 0.1, "rho_local": 0.2,
                "measure": 0.5, "planning_time": t, "time_budget": 1.0, "cost": None,
                "minimum_cost": 1.0, "improvements": 0, "path_states": 0, "explore": True}

    out = {}
    learner._lock.acquire()  # as a checkpoint copying the state holds it
    answers = [call("DecideRequest", decide(agent, t))
               for agent, t in (("psi_K", 0.1), ("B", 0.1), ("psi_K", 0.2))]
    out["answered"] = [ok and "value" in payload for ok, payload in answers]
    out["queued"] = len(learner._unapplied)
    out["recorded_while_locked"] = key in learner.core.pairing.episodes
    ok, payload = call("DecideRequest", decide("psi_K", 0.15))  # before the last one
    out["backwards"] = [ok, payload.get("code"), "before the previous" in payload["message"]]
    learner._lock.release()
    learner.apply_commits()
    out["queued_after"] = len(learner._unapplied)
    out["decisions"] = learner._decisions
    out["last_time"] = learner.core.pairing.episodes[key].last_time
    learner._lock.acquire()
    call("DecideRequest", decide("B", 0.25))
    out["queued_before_end"] = len(learner._unapplied)
    learner._lock.release()
    ok, payload = call("EpisodeEnd", {
        "episode_id": "e1", "planning_time": 0.3, "time_budget": 1.0, "cost": None,
        "minimum_cost": 1.0, "improvements": 0, "path_states": 0, "truncated": False,
        "fallback_decisions": 0})
    out["end"] = [ok, payload.get("transitions_stored"), len(learner._unapplied)]
    out["decisions_at_end"] = learner._decisions
    # A planner that starts another episode has abandoned the one whose end never came.
    for t in (0.1, 0.2):
        call("DecideRequest", dict(decide("psi_K", t), episode_id="e2"))
    out["e2_open"] = "planner/test|run-1|e2" in learner.core.pairing.episodes
    call("DecideRequest", dict(decide("psi_K", 0.05), episode_id="e3"))
    out["e2_after"] = "planner/test|run-1|e2" in learner.core.pairing.episodes
    out["e3_open"] = "planner/test|run-1|e3" in learner.core.pairing.episodes
    out["open_episodes"] = sorted(learner.core.open_episodes())
    out["open_by_source"] = dict(learner._open_episode)
    # e3 idle past episode_timeout (10 s; its budget of 1 s doubled is shorter): abandoned.
    e3 = "planner/test|run-1|e3"
    learner.params["episode_timeout"] = 10.0
    seen, budget, source = learner._last_seen[e3]
    learner._last_seen[e3] = (seen - 9.0, budget, source)
    learner._sweep_idle_episodes()
    learner.apply_commits()  # what the sweep queued (it applies only if the lock is free)
    out["e3_after_9s"] = e3 in learner.core.open_episodes()
    learner._last_seen[e3] = (seen - 11.0, budget, source)
    learner._sweep_idle_episodes()
    learner.apply_commits()
    out["e3_after_11s"] = [e3 in learner.core.open_episodes(), e3 in learner._last_seen,
                           dict(learner._open_episode)]
    episodes = learner.core.episodes
    ok, payload = call("EpisodeEnd", {
        "episode_id": "e3", "planning_time": 0.3, "time_budget": 1.0, "cost": None,
        "minimum_cost": 1.0, "improvements": 0, "path_states": 0, "truncated": False,
        "fallback_decisions": 0})
    out["late_end"] = [ok, payload.get("transitions_stored"), learner.core.episodes - episodes]
    call("DecideRequest", dict(decide("psi_K", 0.05), episode_id="e4"))
    learner.params["episode_timeout"] = 0.5  # but its budget is 1 s: twice that is the limit
    seen, budget, source = learner._last_seen["planner/test|run-1|e4"]
    learner._last_seen["planner/test|run-1|e4"] = (seen - 1.5, budget, source)
    learner._sweep_idle_episodes()
    learner.apply_commits()
    out["e4_within_budget"] = "planner/test|run-1|e4" in learner.core.open_episodes()
    learner._last_seen["planner/test|run-1|e4"] = (seen - 2.5, budget, source)
    learner._sweep_idle_episodes()
    learner.apply_commits()
    out["e4_after_budget"] = "planner/test|run-1|e4" in learner.core.open_episodes()
    # An end the core refuses (earlier than the episode's last decision) leaves it open and
    # tracked: the idle sweep still abandons it.
    e5 = "planner/test|run-1|e5"
    call("DecideRequest", dict(decide("psi_K", 0.5), episode_id="e5"))
    ok, payload = call("EpisodeEnd", {
        "episode_id": "e5", "planning_time": 0.1, "time_budget": 1.0, "cost": None,
        "minimum_cost": 1.0, "improvements": 0, "path_states": 0, "truncated": False,
        "fallback_decisions": 0})
    out["refused_end"] = [ok, payload.get("code"), e5 in learner.core.open_episodes(),
                          e5 in learner._last_seen, learner._open_episode.get("planner/test")]
    seen, budget, source = learner._last_seen[e5]
    learner._last_seen[e5] = (seen - 11.0, budget, source)
    learner.params["episode_timeout"] = 10.0
    learner._sweep_idle_episodes()
    learner.apply_commits()
    out["refused_end_swept"] = e5 in learner.core.open_episodes()
    # Improvements only add up and costs only fall, also against a decision answered but not
    # recorded yet (it was answered, then dropped when its commit failed).
    other = Publisher("planner/other", "run-1")
    learner._lock.acquire()
    more = dict(decide("psi_K", 0.3), episode_id="imp", improvements=3, cost=1.5, path_states=5)
    ok_more, _ = call("DecideRequest", more, other)
    ok_fewer, payload = call("DecideRequest", dict(more, planning_time=0.4, improvements=2), other)
    out["fewer_improvements"] = [ok_more, ok_fewer, payload.get("code"), payload.get("field")]
    ok_dearer, payload = call("DecideRequest", dict(more, planning_time=0.4, cost=1.6), other)
    out["higher_cost"] = [ok_dearer, payload.get("code"), payload.get("field")]
    learner._lock.release()
    learner.apply_commits()
    # A count written as 4.0 (valid JSON for 4) was kept as a float, and the checkpoint holding
    # it was refused at load ("not a whole number").
    ok_float, _ = call("DecideRequest", dict(more, planning_time=0.5, improvements=4.0,
                                             cost=1.4), other)
    learner.apply_commits()
    # A client starting an episode at every request, and ending none, had a warning each time:
    # now for the 1st, 10th, 100th, ... (e3 after e2 was the 1st; these are the 2nd to 12th).
    flood = Publisher("planner/flood", "run-1")
    for n in range(12):
        call("DecideRequest", dict(decide("psi_K", 0.1), episode_id=f"f{n}"), flood)
    learner.apply_commits()
    out["replaced_said"] = [text for text in warnings if "started another one" in text]
    learner.checkpoint()
    from lit_learner.core import LearnerCore
    resumed = LearnerCore.load_checkpoint(f"{folder}/c.pt")
    out["float_count"] = [ok_float, sorted(
        resumed.pairing.episodes["planner/other|run-1|imp"].improvement_times)]
    learner.shutdown()
    learner.node.destroy_node()
    rclpy.shutdown()
    print("RESULT " + json.dumps(out))
    """
)


def test_decisions_answered_while_the_lock_is_taken_are_recorded_after_in_order(
    tmp_path: Path,
) -> None:
    _, out = run_node_script(SCRIPT, str(tmp_path))
    # Answered at once, recorded later: nothing reached the core while the lock was taken.
    assert out["answered"] == [True, True, True]
    assert out["queued"] == 3 and out["recorded_while_locked"] is False
    # A decision earlier than one answered but not yet recorded is still refused.
    assert out["backwards"] == [False, "invalid-request", True]
    # Recorded in order once the lock was free (the last one's time is the episode's latest).
    assert out["queued_after"] == 0 and out["decisions"] == 3 and out["last_time"] == 0.2
    # An episode end records the episode's waiting decisions before closing it.
    assert out["queued_before_end"] == 1
    assert out["end"][0] is True and out["end"][2] == 0
    assert out["decisions_at_end"] == 4
    assert (out["e2_open"], out["e2_after"], out["e3_open"]) == (True, False, True)
    # Nothing of e2 is kept anywhere (pairing, owed steps, reward terms); the ended e1 is not open.
    assert out["open_episodes"] == ["planner/test|run-1|e3"]
    assert list(out["open_by_source"].values()) == ["planner/test|run-1|e3"]
    # An episode without decisions for episode_timeout s is abandoned (not before), and forgotten
    # by its planner's entry too; its end, coming later, stores and counts nothing.
    assert out["e3_after_9s"] is True
    assert out["e3_after_11s"] == [False, False, {}]
    assert out["late_end"] == [True, 0, 0]
    # The limit is twice the episode's time budget when that is longer.
    assert out["e4_within_budget"] is True and out["e4_after_budget"] is False
    # A refused end leaves the episode open and tracked, so the sweep can still abandon it.
    assert out["refused_end"] == [False, "invalid-request", True, True, "planner/test|run-1|e5"]
    assert out["refused_end_swept"] is False
    assert out["fewer_improvements"] == [True, False, "invalid-request", "$.payload.improvements"]
    assert out["higher_cost"] == [False, "invalid-request", "$.payload.cost"]
    assert out["float_count"] == [True, [0, 3, 4]]
    said = out["replaced_said"]
    assert len(said) == 2, said
    assert (
        "planner/test|run-1|e2 never ended (its planner started another one; 1 so far)" in said[0]
    )
    assert "f8 never ended (its planner started another one; 10 so far)" in said[1], said
