"""Double DQN (van Hasselt et al. 2016) as the paper uses it (§III-B/C), in a few readable pieces.

    Y = R + γⁿ · Q_θ̄(s′, argmax_a′ Q_θ(s′, a′))      (stop-gradient; Y = R at a termination)
    L = mean over the minibatch of ℓ(Q_θ(s, a) − Y)   (ℓ = square (paper) or Huber)
    θ̄ ← (1 − τ) θ̄ + τ θ                              (after every gradient step)

With ``n_step = 1`` R is the reward and γⁿ = γ — exactly the paper's target.
Exploration samples π(a|s) ∝ exp(Q_θ(s, a)/β); evaluation is greedy.

Optionally (DQfD, Hester et al. 2018) minibatches also hold a reference planner's transitions, on
which a large-margin loss makes the demonstrated action the greedy one unless another action is
worth ``margin`` more:  L_E = max_a [Q(s, a) + margin·(a ≠ a_E)] − Q(s, a_E).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


def mask_unsafe(q: torch.Tensor, safe: torch.Tensor | None) -> torch.Tensor:
    """Q-values (N, 5) with the actions outside ``safe`` (N, 5 bool; None: all allowed) at −∞,
    so argmax and soft-max choose among the allowed ones (invalid-action masking, Huang &
    Ontañón 2022). A row with no allowed action is left as it is."""
    if safe is None:
        return q
    safe = safe | ~safe.any(dim=1, keepdim=True)
    return q.masked_fill(~safe, float("-inf"))


@torch.no_grad()
def ddqn_target(
    online: nn.Module,
    target: nn.Module,
    next_grid: torch.Tensor,
    next_budget: torch.Tensor,
    returns: torch.Tensor,
    discount: torch.Tensor,
    next_safe: torch.Tensor | None = None,
) -> torch.Tensor:
    """Y = R + discount · Q_θ̄(s′, argmax_a′ Q_θ(s′, a′)); discount = γⁿ, or 0 if terminated.
    With ``next_safe`` the argmax runs over those actions only: the policy acts so."""
    best = mask_unsafe(online(next_grid, next_budget), next_safe).argmax(dim=1, keepdim=True)
    value = target(next_grid, next_budget).gather(1, best).squeeze(1)
    return returns + discount * value


@torch.no_grad()
def soft_update(target: nn.Module, online: nn.Module, tau: float) -> None:
    """θ̄ ← (1 − τ) θ̄ + τ θ for every parameter (and buffer)."""
    t_params = [p for p in target.parameters()] + [
        b for b in target.buffers() if b.is_floating_point()
    ]
    o_params = [p for p in online.parameters()] + [
        b for b in online.buffers() if b.is_floating_point()
    ]
    torch._foreach_lerp_(t_params, o_params, tau)


@torch.no_grad()
def softmax_actions(
    q: torch.Tensor, beta: float, generator: torch.Generator | None = None
) -> torch.Tensor:
    """Sample one action per row from π(a|s) = softmax(Q(s, ·)/β)."""
    probs = torch.softmax(q / beta, dim=1)
    return torch.multinomial(probs, 1, generator=generator).squeeze(1)


def td_loss(q_taken: torch.Tensor, y: torch.Tensor, kind: str = "mse") -> torch.Tensor:
    if kind == "mse":
        return F.mse_loss(q_taken, y)
    if kind == "huber":
        return F.smooth_l1_loss(q_taken, y)
    raise ValueError(f"unknown loss {kind!r}")


def margin_loss(
    q: torch.Tensor, action: torch.Tensor, demo: torch.Tensor, margin: float
) -> torch.Tensor:
    """DQfD's large-margin loss, averaged over the rows where ``demo`` is true (a_E = action)."""
    bonus = torch.full_like(q, margin).scatter(1, action[:, None], 0.0)
    gap = (q + bonus).max(dim=1).values - q.gather(1, action[:, None]).squeeze(1)
    weight = demo.to(q.dtype)
    return (gap * weight).sum() / weight.sum().clamp(min=1.0)


def ddqn_update(
    online: nn.Module,
    target: nn.Module,
    optimizer: torch.optim.Optimizer,
    batch: dict[str, torch.Tensor],
    *,
    tau: float,
    loss_kind: str = "mse",
    max_grad_norm: float = 0.0,
    margin: float = 0.0,
    margin_weight: float = 1.0,
) -> dict[str, float]:
    """One gradient step on a minibatch, then the soft target update. Returns loss and mean Q.

    With ``batch["demo"]`` (a bool mask of demonstrated rows) the large-margin loss is added;
    with ``batch["next_safe"]`` the target's argmax is masked (:func:`mask_unsafe`)."""
    y = ddqn_target(
        online, target, batch["next_grid"], batch["next_budget"], batch["return"],
        batch["discount"], batch.get("next_safe"),
    )  # fmt: skip
    q = online(batch["grid"], batch["budget"])
    q_taken = q.gather(1, batch["action"][:, None]).squeeze(1)
    loss = td_loss(q_taken, y, loss_kind)
    if "demo" in batch and margin_weight > 0:
        loss = loss + margin_weight * margin_loss(q, batch["action"], batch["demo"], margin)
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    if max_grad_norm > 0:
        nn.utils.clip_grad_norm_(online.parameters(), max_grad_norm)
    optimizer.step()
    soft_update(target, online, tau)
    return {"loss": float(loss.detach()), "q": float(q_taken.detach().mean())}
