"""Message -> transition pairing: consecutive requests, episode ends, interleaved episodes."""

from __future__ import annotations

import pytest
from lit_learner.config import RewardConfig
from lit_learner.errors import PairingError
from lit_learner.messages import DecisionRequest, EpisodeEnd
from lit_learner.pairing import Pairing
from lit_learner.rewards import batch_size_reward, neighbour_reward, search_cost

REWARD = RewardConfig()


def request(
    agent: str,
    episode: str,
    t: float,
    features: float,
    improvements: int = 0,
    cost: float | None = None,
    path_states: int = 0,
) -> DecisionRequest:
    return DecisionRequest(
        agent,
        episode,
        features,
        features,
        features,
        t,
        10.0,
        cost,
        2.0,
        improvements,
        path_states,
    )


def test_consecutive_requests_of_one_agent_form_a_transition() -> None:
    pairing = Pairing(REWARD)
    assert pairing.step(request("psi_K", "e", 0.0, 0.1), 0.3) is None
    assert pairing.step(request("B", "e", 0.0, 0.2), 0.6) is None  # other agent: own pending
    t = pairing.step(request("psi_K", "e", 1.5, 0.4, improvements=1, cost=4.0, path_states=25), 0.7)
    assert t is not None
    assert (t.agent, t.episode_id, t.state, t.action, t.next_state) == (
        "psi_K",
        "e",
        (0.1, 0.1, 0.1),
        0.3,
        (0.4, 0.4, 0.4),
    )
    assert not t.terminated and not t.truncated
    # The step ran from t = 0 without a solution until 1.5: all of it was search time.
    assert t.reward == neighbour_reward(True, 1.5, 10.0, 4.0, 2.0, 25, REWARD, search=(0.0, 1.5))


def test_only_steps_taken_before_the_first_solution_pay_search_time() -> None:
    pairing = Pairing(REWARD)
    pairing.step(request("psi_K", "e", 0.5, 0.1), 0.3)
    t1 = pairing.step(request("psi_K", "e", 0.75, 0.1), 0.3)
    t2 = pairing.step(request("psi_K", "e", 2.0, 0.1, improvements=1, cost=4.0), 0.3)
    t3 = pairing.step(request("psi_K", "e", 3.0, 0.1, improvements=1, cost=4.0), 0.3)
    assert t1 is not None and t2 is not None and t3 is not None
    assert t1.reward.total == pytest.approx(-search_cost(0.5, 0.75, 10.0, REWARD))
    assert t2.reward.time == pytest.approx(REWARD.w_t / 0.2)
    assert t2.reward.search == pytest.approx(-search_cost(0.75, 2.0, 10.0, REWARD))
    assert t3.reward.total == 0.0


def test_step_time_runs_from_the_previous_improvement() -> None:
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 0.0, 0.1), 0.5)
    t1 = pairing.step(request("B", "e", 2.0, 0.1, improvements=1, cost=8.0), 0.5)
    pairing.step(request("psi_K", "e", 3.0, 0.1, improvements=1, cost=8.0), 0.5)
    t2 = pairing.step(request("B", "e", 5.0, 0.1, improvements=2, cost=4.0), 0.5)
    t3 = pairing.step(request("B", "e", 6.0, 0.1, improvements=2, cost=4.0), 0.5)
    assert t1 is not None and t2 is not None and t3 is not None
    assert t1.reward == batch_size_reward(True, 1, 2.0, 10.0, 8.0, 2.0, REWARD)
    assert t2.reward == batch_size_reward(True, 2, 3.0, 10.0, 4.0, 2.0, REWARD)
    assert t3.reward == batch_size_reward(False, 2, 0.0, 10.0, 4.0, 2.0, REWARD)
    assert t3.reward.total == pytest.approx(-0.1)


def test_progress_from_another_policys_decision_keeps_improvement_times_exact() -> None:
    """lit train's psi_K phase takes B from a tensor (no step of it): the B decision at each
    improvement still tells the pairing when it came, instead of the next psi_K request."""
    exact, late = Pairing(REWARD), Pairing(REWARD)
    for pairing in (exact, late):
        pairing.step(request("psi_K", "e", 0.0, 0.1), 0.5)
    exact.progress(request("B", "e", 2.0, 0.1, improvements=1, cost=8.0))  # at the improvement
    t_exact = exact.step(request("psi_K", "e", 4.5, 0.1, improvements=1, cost=8.0), 0.5)
    t_late = late.step(request("psi_K", "e", 4.5, 0.1, improvements=1, cost=8.0), 0.5)
    assert t_exact is not None and t_late is not None
    assert t_exact.reward.time == pytest.approx(REWARD.w_t / 0.2)  # t = 2.0 of T = 10
    assert t_late.reward.time == pytest.approx(REWARD.w_t / 0.45)  # t = 4.5: the request's time
    assert "B" not in exact.episodes["e"].pending  # no step of B
    # The step's search ended at the first solution (2.0), not at the request (4.5).
    assert t_exact.reward.search == pytest.approx(-search_cost(0.0, 2.0, 10.0, REWARD))
    assert t_late.reward.search == pytest.approx(-search_cost(0.0, 4.5, 10.0, REWARD))
    # Also when the first count seen is above 1 (the planner missed calls meanwhile).
    skipped = Pairing(REWARD)
    skipped.step(request("psi_K", "e", 0.5, 0.1), 0.5)
    skipped.progress(request("B", "e", 2.0, 0.1, improvements=2, cost=8.0))
    t_skip = skipped.step(request("psi_K", "e", 4.5, 0.1, improvements=2, cost=8.0), 0.5)
    assert t_skip is not None
    assert t_skip.reward.search == pytest.approx(-search_cost(0.5, 2.0, 10.0, REWARD))


@pytest.mark.parametrize("truncated", [True, False])
def test_episode_end_closes_every_pending_step(truncated: bool) -> None:
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 0.0, 0.2), 0.6)
    pairing.step(request("psi_K", "e", 0.5, 0.3), 0.1)
    end = EpisodeEnd(
        "e",
        10.0,
        10.0,
        4.0,
        2.0,
        1,
        30,
        truncated=truncated,
        final_features={"psi_K": (0.9, 0.8, 0.7)},
    )
    closed, returns = pairing.end(end)
    assert [t.agent for t in closed] == ["B", "psi_K"]
    b, k = closed
    assert b.next_state == (0.2, 0.2, 0.2)  # no final features for B: its last state
    assert k.next_state == (0.9, 0.8, 0.7)
    for t in closed:
        assert t.truncated is truncated and t.terminated is (not truncated)
    assert b.reward == batch_size_reward(True, 1, 10.0, 10.0, 4.0, 2.0, REWARD)
    assert returns == {"B": pytest.approx(b.reward.total), "psi_K": pytest.approx(k.reward.total)}
    assert pairing.episodes == {}
    assert pairing.end(end) == ([], {})  # a second end of the same episode closes nothing


def test_steps_whose_actions_were_not_executed_are_dropped() -> None:
    """LEARNER.md: the executed value is stored. A planner that executed fallback values (the
    learner answered too late, or was not asked) says so with its agent's next request
    (``after_fallback``) and at the end (``fallback_agents``): the pending step of that agent is
    dropped, not closed into a transition with an action that did not run."""
    from dataclasses import replace

    pairing = Pairing(REWARD)
    pairing.step(request("psi_K", "e", 0.0, 0.1), 0.1)
    kept = pairing.step(request("psi_K", "e", 0.5, 0.2), 0.2)  # its answer came too late
    assert kept is not None and kept.action == 0.1  # 0.1 ran from 0.0 to 0.5: a true step
    after = replace(request("psi_K", "e", 1.5, 0.3), after_fallback=True)
    assert pairing.step(after, 0.3) is None  # 0.2 never ran: dropped
    pairing.step(request("B", "e", 1.6, 0.4), 0.4)
    last = pairing.step(request("psi_K", "e", 2.0, 0.5), 0.5)
    assert last is not None and (last.state, last.action) == ((0.3,) * 3, 0.3)

    end = EpisodeEnd("e", 10.0, 10.0, None, 2.0, 0, 0, fallback_agents=("psi_K",))
    closed, _ = pairing.end(end)
    assert [t.agent for t in closed] == ["B"]  # psi_K's last step ended in fallback values


def test_interleaved_episodes_are_kept_apart() -> None:
    pairing = Pairing(REWARD)
    pairing.step(request("B", "a", 0.0, 0.1), 0.1)
    pairing.step(request("B", "b", 0.0, 0.5), 0.5)
    ta = pairing.step(request("B", "a", 1.0, 0.2, improvements=1, cost=4.0), 0.2)
    tb = pairing.step(request("B", "b", 0.5, 0.6), 0.6)
    assert ta is not None and tb is not None
    assert (ta.episode_id, ta.state, ta.next_state, ta.action) == ("a", (0.1,) * 3, (0.2,) * 3, 0.1)
    assert (tb.episode_id, tb.state, tb.next_state, tb.action) == ("b", (0.5,) * 3, (0.6,) * 3, 0.5)
    assert ta.reward.cost > 0.0 and tb.reward.total == 0.0  # b has no improvement
    closed, _ = pairing.end(EpisodeEnd("a", 10.0, 10.0, 4.0, 2.0, 1, 5))
    assert [t.episode_id for t in closed] == ["a"]
    assert set(pairing.episodes) == {"b"}


def test_untrained_agent_records_nothing() -> None:
    pairing = Pairing(REWARD)
    assert pairing.step(request("B", "e", 0.0, 0.1), None) is None
    assert pairing.step(request("B", "e", 1.0, 0.1), None) is None
    assert pairing.end(EpisodeEnd("e", 2.0, 10.0, None, 2.0, 0, 0)) == ([], {})


def test_time_running_backwards_is_an_error() -> None:
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 2.0, 0.1), 0.1)
    with pytest.raises(PairingError, match=r"episode 'e': planning_time 1.0 is before"):
        pairing.step(request("psi_K", "e", 1.0, 0.1), 0.1)


def test_an_improvement_count_that_goes_down_is_an_error_that_changes_nothing() -> None:
    """It was a KeyError from the step-time lookup, raised by ``end`` after the episode was
    forgotten (its pending steps lost), which the learner node did not catch."""
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 1.0, 0.1, improvements=3, cost=3.0, path_states=4), 0.1)
    with pytest.raises(PairingError, match=r"episode 'e': improvements 2 is below the 3") as caught:
        pairing.step(request("B", "e", 2.0, 0.1, improvements=2, cost=3.0, path_states=4), 0.1)
    assert caught.value.field == "improvements"
    with pytest.raises(PairingError, match=r"improvements 2 is below the 3"):
        pairing.end(EpisodeEnd("e", 3.0, 10.0, 3.0, 2.0, 2, 4))
    assert set(pairing.episodes["e"].pending) == {"B"}  # still open, its step kept
    closed, _ = pairing.end(EpisodeEnd("e", 3.0, 10.0, 3.0, 2.0, 3, 4))
    assert len(closed) == 1


@pytest.mark.parametrize("cost", [3.5, None])
def test_a_best_cost_that_rises_or_is_lost_is_an_error_that_changes_nothing(
    cost: float | None,
) -> None:
    """A cost above one reported before (or none after a solution) was taken, and R_B / R_K
    rewarded it as the path's new quality; a best cost only falls."""
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 1.0, 0.1, improvements=1, cost=3.0, path_states=4), 0.1)
    pairing.step(request("psi_K", "e", 1.5, 0.1, improvements=1, cost=3.0, path_states=4), 0.1)
    shown = r"no cost \(no solution\)" if cost is None else rf"cost {cost} is above"
    with pytest.raises(PairingError, match=rf"episode 'e': {shown} after the cost 3.0 an earlier"):
        pairing.check(request("B", "e", 2.0, 0.1, improvements=1, cost=cost, path_states=4))
    with pytest.raises(PairingError, match=r"a best cost only falls") as caught:
        pairing.step(request("psi_K", "e", 2.0, 0.1, improvements=2, cost=cost, path_states=4), 0.1)
    assert caught.value.field == "cost"
    with pytest.raises(PairingError, match=r"a best cost only falls"):
        pairing.end(EpisodeEnd("e", 3.0, 10.0, cost, 2.0, 2, 4))
    assert set(pairing.episodes["e"].pending) == {"B", "psi_K"}  # still open, its steps kept
    # The same cost again and a lower one are taken, also after a checkpoint round trip.
    pairing.step(request("B", "e", 2.0, 0.1, improvements=1, cost=3.0, path_states=4), 0.1)
    copy = Pairing(REWARD)
    copy.load_state_dict(pairing.state_dict())
    with pytest.raises(PairingError, match=r"a best cost only falls"):
        copy.end(EpisodeEnd("e", 3.0, 10.0, cost, 2.0, 2, 4))
    closed, _ = copy.end(EpisodeEnd("e", 3.0, 10.0, 2.5, 2.0, 2, 4))
    assert len(closed) == 2


def test_a_cost_a_rounding_above_the_best_is_taken_and_moves_nothing() -> None:
    """The episode end's cost is the path's length summed again: on a machine whose OMPL fuses
    multiply-adds (arm64) it can be an ulp above the decisions' best cost, and the end was
    refused (the episode abandoned)."""
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 1.0, 0.1, improvements=1, cost=3.0, path_states=4), 0.1)
    above = 3.0 * (1.0 + 1e-12)
    pairing.step(request("B", "e", 2.0, 0.1, improvements=1, cost=above, path_states=4), 0.1)
    assert pairing.episodes["e"].best_cost == 3.0
    with pytest.raises(PairingError, match=r"a best cost only falls"):
        pairing.check(request("B", "e", 2.0, 0.1, improvements=1, cost=3.0001, path_states=4))
    closed, _ = pairing.end(EpisodeEnd("e", 3.0, 10.0, above, 2.0, 1, 4))
    assert len(closed) == 1


def test_a_checkpoint_without_the_best_cost_still_loads() -> None:
    """Checkpoints written before the pairing kept the best cost: the check starts at the next
    solution."""
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 1.0, 0.1, improvements=1, cost=3.0, path_states=4), 0.1)
    state = pairing.state_dict()
    del state["e"]["best_cost"]
    copy = Pairing(REWARD)
    copy.load_state_dict(state)
    assert copy.episodes["e"].best_cost is None
    copy.step(request("B", "e", 2.0, 0.1, improvements=2, cost=2.5, path_states=4), 0.1)
    assert copy.episodes["e"].best_cost == 2.5


def test_an_end_before_the_last_decision_is_refused_and_the_episode_stays_open() -> None:
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 2.0, 0.1), 0.1)
    with pytest.raises(PairingError, match=r"episode 'e': planning_time 1.0 is before"):
        pairing.end(EpisodeEnd("e", 1.0, 10.0, None, 2.0, 0, 0))
    assert "e" in pairing.episodes  # still open: its planner's next episode abandons it
    assert pairing.abandon("e")


def test_state_round_trip() -> None:
    pairing = Pairing(REWARD)
    pairing.step(request("B", "e", 0.0, 0.1), 0.1)
    pairing.step(request("B", "e", 1.0, 0.2, improvements=1, cost=3.0), 0.2)
    copy = Pairing(REWARD)
    copy.load_state_dict(pairing.state_dict())
    nxt = request("B", "e", 2.0, 0.3, improvements=2, cost=2.5)
    assert copy.step(nxt, 0.3) == pairing.step(nxt, 0.3)


def test_episode_keys_of_different_clients_differ_whatever_bars_their_names_hold() -> None:
    from lit_learner.messages import episode_key

    assert episode_key("/lit/planner", "run", "ep-1") == "/lit/planner|run|ep-1"  # as before
    names = [("pl|X", "r", "e"), ("pl", "X|r", "e"), ("pl", "X", "r|e"), ("pl\\", "|r", "e"),
             ("pl\\|", "r", "e"), ("pl", "\\|r", "e"), ("", "", "pl|X|r|e")]  # fmt: skip
    assert len({episode_key(*name) for name in names}) == len(names)
