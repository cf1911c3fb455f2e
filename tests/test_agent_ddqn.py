"""DDQN pieces on hand-computed numbers: target, soft update, soft-max sampling, n-step replay."""

import numpy as np
import pytest
import torch
from torch import nn

from cpp_mujoco.agent.ddqn import (
    ddqn_target,
    ddqn_update,
    margin_loss,
    soft_update,
    softmax_actions,
)
from cpp_mujoco.agent.replay import ReplayBuffer


class Table(nn.Module):
    """Q(s, ·) read from a fixed table; the state is the row index stored in the budget input."""

    def __init__(self, q):
        super().__init__()
        self.q = nn.Parameter(torch.tensor(q, dtype=torch.float32))

    def forward(self, grid, budget):
        return self.q[budget.reshape(-1).long()]


def _terminal_batch(action: int, ret: float, next_state: float) -> dict[str, torch.Tensor]:
    """A one-transition minibatch from state 0 that terminates (Y = ret)."""
    return {
        "grid": torch.zeros(1, 1),
        "budget": torch.tensor([[0.0]]),
        "action": torch.tensor([action]),
        "return": torch.tensor([ret]),
        "next_grid": torch.zeros(1, 1),
        "next_budget": torch.tensor([[next_state]]),
        "discount": torch.tensor([0.0]),
    }


def test_ddqn_target_hand_computed():
    online = Table([[1.0, 5.0, 2.0], [9.0, 0.0, 3.0]])  # argmax: action 1, action 0
    target = Table([[10.0, 20.0, 30.0], [40.0, 50.0, 60.0]])
    next_state = torch.tensor([[0.0], [1.0], [1.0]])
    r = torch.tensor([1.0, -2.0, 0.5])
    discount = torch.tensor([0.95, 0.95, 0.0])  # the third is terminal: Y = r
    y = ddqn_target(online, target, torch.zeros(3, 1), next_state, r, discount)
    # evaluated by the target net at the ONLINE argmax (20 and 40), not the target's own max
    assert torch.allclose(y, torch.tensor([1.0 + 0.95 * 20.0, -2.0 + 0.95 * 40.0, 0.5]))
    assert not y.requires_grad  # stop-gradient


def test_update_moves_q_towards_target_and_gradient_stops_at_y():
    online = Table([[0.0, 0.0], [0.0, 0.0]])
    target = Table([[0.0, 0.0], [0.0, 0.0]])
    opt = torch.optim.SGD(online.parameters(), lr=0.5)
    batch = _terminal_batch(action=1, ret=2.0, next_state=1.0)
    stats = ddqn_update(online, target, opt, batch, tau=1.0, loss_kind="mse")
    assert stats["loss"] == pytest.approx(4.0)
    # d/dq (q - 2)^2 = -4 → q = 0 + 0.5 * 4 = 2; only the taken action moves
    assert online.q[0].tolist() == pytest.approx([0.0, 2.0])
    assert torch.equal(target.q, online.q)  # tau = 1 copies


def test_soft_update():
    a, b = nn.Linear(3, 2), nn.Linear(3, 2)
    before = [p.clone() for p in b.parameters()]
    soft_update(b, a, tau=0.005)
    for pb, pa, p0 in zip(b.parameters(), a.parameters(), before, strict=True):
        assert torch.allclose(pb, 0.995 * p0 + 0.005 * pa)


def test_softmax_exploration_frequencies():
    beta = 0.1
    q = torch.tensor([[0.0, beta * np.log(2), beta * np.log(4), -10.0, 0.0]])
    expected = np.array([1, 2, 4, 0, 1]) / 8
    gen = torch.Generator().manual_seed(0)
    n = 40_000
    a = softmax_actions(q.expand(n, 5), beta, gen).numpy()
    freq = np.bincount(a, minlength=5) / n
    assert np.allclose(freq, expected, atol=0.01)
    assert freq[3] < 1e-3


def test_replay_n_step_returns_stop_at_termination():
    layers = np.zeros((3, 2, 2), dtype=bool)
    rb = ReplayBuffer(capacity=100, num_envs=1, map_layers=layers, n_step=3, gamma=0.5)
    rewards = [1.0, 2.0, 4.0, 8.0, 16.0]
    terminated = [False, True, False, False, False]
    for i, (r, d) in enumerate(zip(rewards, terminated, strict=True)):
        pos = np.zeros((1, 2, 2), np.int8)
        pos.reshape(-1)[i % 4] = 1
        obs = {
            "coverage": np.zeros((1, 2, 2), np.int8),
            "position": pos,
            "budget": np.array([[10.0 + i]]),
        }
        rb.add(obs, [i % 5], [r], [d])
    rng = np.random.default_rng(0)
    seen = {}
    for _ in range(50):
        s = rb.sample(8, rng)
        for b, ret, disc, nb in zip(
            s["obs"][1][:, 0], s["return"], s["discount"], s["next_obs"][1][:, 0], strict=True
        ):
            seen[int(b) - 10] = (float(ret), float(disc), int(nb) - 10)
    assert set(seen) == {0, 1}  # rows 2..4 lack 3 following rows
    assert seen[0][:2] == (1.0 + 0.5 * 2.0, 0.0)  # terminates at step 1
    assert seen[1][:2] == (2.0, 0.0)


def test_margin_loss_hand_computed():
    q = torch.tensor([[1.0, 3.0, 2.0], [5.0, 1.0, 0.0], [0.0, 9.0, 0.0]])
    action = torch.tensor([2, 0, 0])
    demo = torch.tensor([True, True, False])  # the third row is the agent's own: no margin loss
    # row 0: max(1+.5, 3+.5, 2) − 2 = 1.5;  row 1: demonstrated action already best by > .5 → 0
    assert margin_loss(q, action, demo, 0.5).item() == pytest.approx((1.5 + 0.0) / 2)
    assert margin_loss(q, action, torch.zeros(3, dtype=torch.bool), 0.5).item() == 0.0


def test_margin_loss_makes_the_demonstrated_action_greedy():
    online, target = Table([[0.0, 1.0, 0.0]]), Table([[0.0, 1.0, 0.0]])
    opt = torch.optim.SGD(online.parameters(), lr=0.1)
    batch = {**_terminal_batch(action=2, ret=0.0, next_state=0.0), "demo": torch.tensor([True])}
    for _ in range(100):
        ddqn_update(online, target, opt, batch, tau=0.0, loss_kind="huber", margin=0.5)
    assert int(online.q[0].argmax()) == 2  # the demonstrator's action, against the initial Q
    batch["demo"] = torch.tensor([False])
    without = Table([[0.0, 1.0, 0.0]])
    opt = torch.optim.SGD(without.parameters(), lr=0.1)
    for _ in range(100):
        ddqn_update(without, target, opt, batch, tau=0.0, loss_kind="huber", margin=0.5)
    assert int(without.q[0].argmax()) == 1  # TD alone drives Q(s, 2) to 0 only
