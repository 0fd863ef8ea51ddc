"""The one rule for an adversary and its target (`sim.terms.pair_problem`), which `simulate`, the env, a suite and
the studio all apply."""

from __future__ import annotations

from langtraj.sim.terms import pair_problem


def test_a_pair_is_both_or_neither_two_agents_never_the_ego_and_in_the_scene_where_it_is_known():
    assert pair_problem(None, None) is None and pair_problem(3, 4) is None
    assert pair_problem(3, None) == ("target", "an adversary needs a target and a target an adversary")
    assert pair_problem(None, 4)[0] == "adversary"
    assert pair_problem(3, 3) == ("target", "the adversary and the target are the same agent (@3)")
    assert pair_problem(3, "ego", ego=3)[0] == "adversary"  # the ego's id known (the env)
    assert pair_problem("ego", 4, ego="ego")[0] == "adversary"  # before it is (a suite)
    assert pair_problem(3, "ego", ego=None) is None
    where, why = pair_problem(3, 9, sim_ids={3, 4})
    assert where == "target" and why.startswith(
        "@9 is not an agent of this scene at its current step; sim agents: 3, 4"
    )
    assert pair_problem(3, 4, sim_ids={3, 4}, driven={3}) == ("target", "@4 is not among the 1 agents the model drives")
