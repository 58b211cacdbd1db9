"""A small 1-D CNN on canonical windows: class logits and log(beta).

* Input: :func:`stiffnet.features.windows.window_tensor`, shape ``(N, C, L)``:
  the canonical window (``rate`` samples per natural period, ``periods``
  periods, spikes up, unit std) and its delay copies as channels.
* :class:`StiffnessCNN`: ``n_blocks`` Conv1d-BatchNorm-ReLU blocks (the first
  at stride 1, then stride 2 each, so L halves per later block), global average
  pooling, dropout and two linear heads: ``n_classes`` logits (no_contact +
  beta classes) and one ``log(beta)``.
* :func:`fit_cnn`: Adam, fixed seeds, class-balanced cross-entropy plus
  ``beta_loss_weight`` x MSE on ``log(beta)`` of the *true-contact* windows
  (the log-beta target is standardised with the training mean and std and
  de-standardised inside the model, so the exported graph outputs log(beta)
  directly), early stopping on the validation trajectories' loss (the best
  epoch's weights are kept).
* :func:`predict_cnn`: probabilities and log(beta) in batches.

Splits, the conformal half-width and the metrics are those every family uses
(:mod:`training.split`, :mod:`training.finish`, :mod:`training.metrics`);
end-to-end training: :mod:`training.families.cnn.train`.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import nn

from training.families.cnn.config import CNNConfig
from training.metrics import NO_CONTACT_LABEL
from training.split import Split

#: Weight of the scale head's likelihood term in the loss.
SCALE_LOSS_WEIGHT = 0.2


class StiffnessCNN(nn.Module):
    """Conv1d-BN-ReLU blocks, global average pooling, class and log-beta heads.

    Parameters
    ----------
    in_channels : int
        Input channels (delay copies).
    n_classes : int
        Number of class logits.
    width, n_blocks, kernel_size, dropout
        Architecture (see :class:`~training.families.cnn.config.CNNConfig`).
    log_beta_mean, log_beta_std : float
        Standardisation of the regression target (the head predicts the
        standardised value; :meth:`forward` returns log(beta)).
    """

    def __init__(
        self,
        in_channels: int,
        n_classes: int,
        width: int = 32,
        n_blocks: int = 4,
        kernel_size: int = 7,
        dropout: float = 0.1,
        log_beta_mean: float = 0.0,
        log_beta_std: float = 1.0,
    ) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        c = in_channels
        for i in range(n_blocks):
            layers += [
                nn.Conv1d(
                    c, width, kernel_size, stride=1 if i == 0 else 2, padding=kernel_size // 2
                ),
                nn.BatchNorm1d(width),
                nn.ReLU(),
            ]
            c = width
        self.features = nn.Sequential(*layers)
        self.dropout = nn.Dropout(dropout)
        self.cls = nn.Linear(width, n_classes)
        self.reg = nn.Linear(width, 1)
        self.scale = nn.Linear(width, 1)
        self.register_buffer("beta_mean", torch.tensor(float(log_beta_mean)))
        self.register_buffer("beta_std", torch.tensor(float(log_beta_std)))

    def heads(
        self, x: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Logits, log(beta), log of its expected error ``(N, 1)`` and the embedding.

        The embedding is the pooled feature vector ``(N, width)`` the heads read:
        what the alarm compares with the training data. The scale head estimates
        the size of the log-beta error of this window (heteroscedastic), which
        normalises the conformal interval.
        """
        e = self.features(x).mean(dim=2)
        h = self.dropout(e)
        log_beta = self.reg(h) * self.beta_std + self.beta_mean
        return self.cls(h), log_beta, self.scale(h) + torch.log(self.beta_std), e

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Class logits ``(N, n_classes)`` and log(beta) ``(N, 1)``."""
        logits, log_beta, _, _ = self.heads(x)
        return logits, log_beta


class ProbabilityModel(nn.Module):
    """Export wrapper: softmax probabilities and log(beta)."""

    def __init__(self, net: StiffnessCNN) -> None:
        super().__init__()
        self.net = net

    def forward(self, windows: torch.Tensor) -> tuple[torch.Tensor, ...]:
        logits, log_beta, log_scale, embedding = self.net.heads(windows)
        return torch.softmax(logits, dim=1), log_beta, log_scale, embedding


@dataclass
class FitResult:
    """The fitted network (eval mode, best epoch) and its training history."""

    model: StiffnessCNN
    best_epoch: int
    epochs: int
    seconds: float
    history: list[dict[str, float]] = field(default_factory=list)


def _class_weights(y: np.ndarray, n_classes: int, mode: str | None) -> torch.Tensor:
    if mode != "balanced":
        return torch.ones(n_classes)
    counts = np.bincount(y, minlength=n_classes).astype(np.float64)
    w = np.where(counts > 0, y.size / (n_classes * np.maximum(counts, 1)), 0.0)
    return torch.tensor(w, dtype=torch.float32)


def _loss(
    model: StiffnessCNN,
    x: torch.Tensor,
    y: torch.Tensor,
    lb: torch.Tensor,
    ce: nn.Module,
    beta_weight: float,
) -> torch.Tensor:
    logits, log_beta, log_scale, _ = model.heads(x)
    loss = ce(logits, y)
    contact = y != NO_CONTACT_LABEL
    if beta_weight > 0 and bool(contact.any()):
        r = log_beta[:, 0][contact] - lb[contact]
        loss = loss + beta_weight * torch.mean((r / model.beta_std) ** 2)
        # Gaussian likelihood of the (detached) error under the predicted scale: the
        # scale head learns how wrong this kind of window tends to be without pulling
        # on the beta estimate itself.
        s = log_scale[:, 0][contact]
        loss = loss + SCALE_LOSS_WEIGHT * torch.mean(0.5 * (r.detach() * torch.exp(-s)) ** 2 + s)
    return loss


def _train_epoch(
    model: StiffnessCNN, opt: torch.optim.Optimizer, perm: np.ndarray, batch_size: int, data: tuple
) -> float:
    """One pass over the training windows in the order `perm`; their mean loss."""
    Xt, yt, lbt, ce, beta_weight = data
    model.train()
    total = 0.0
    for i in range(0, perm.size, batch_size):
        b = torch.from_numpy(np.sort(perm[i : i + batch_size]))
        if b.numel() < 2:  # BatchNorm needs two samples
            continue
        opt.zero_grad()
        loss = _loss(model, Xt[b], yt[b], lbt[b], ce, beta_weight)
        loss.backward()
        opt.step()
        total += loss.item() * b.numel()
    return total / max(1, perm.size)


def _validation_loss(model: StiffnessCNN, va: np.ndarray, data: tuple) -> float:
    """The loss on the validation windows (the early-stopping criterion)."""
    Xt, yt, lbt, ce, beta_weight = data
    model.eval()
    with torch.no_grad():
        v = torch.from_numpy(va)
        return float(_loss(model, Xt[v], yt[v], lbt[v], ce, beta_weight))


def fit_cnn(
    X: np.ndarray,
    label: np.ndarray,
    beta: np.ndarray,
    split: Split,
    n_classes: int,
    cfg: CNNConfig,
    seed: int,
    progress: Callable[[str], None] | None = None,
    on_epoch: Callable[[dict[str, float]], None] | None = None,
) -> FitResult:
    """Train the CNN on ``split.train``, early-stopping on ``split.val``.

    Parameters
    ----------
    X : numpy.ndarray
        Inputs of all windows, float32 ``(n, C, L)``.
    label : numpy.ndarray
        Class index (0 = no contact).
    beta : numpy.ndarray
        True stiffness ratio (used for contact windows only).
    split : Split
        Trajectory-wise split.
    n_classes : int
        Number of classes (no_contact included).
    cfg : CNNConfig
        Hyper-parameters.
    seed : int
        Seed of the weights, the batch order and dropout.
    progress : callable, optional
        Receives one line per epoch.
    on_epoch : callable, optional
        Receives each epoch's history entry (``epoch``, ``train_loss``,
        ``val_loss``) as it ends (progress bars, experiment trackers).

    Returns
    -------
    FitResult
        The best-validation-loss model in eval mode.
    """
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    label = np.asarray(label, dtype=np.int64)
    log_beta = np.log(np.where(label != NO_CONTACT_LABEL, beta, 1.0)).astype(np.float32)
    tr = np.flatnonzero(split.train)
    va = np.flatnonzero(split.val)
    tr_contact = tr[label[tr] != NO_CONTACT_LABEL]
    mu = float(log_beta[tr_contact].mean()) if tr_contact.size else 0.0
    sd = float(log_beta[tr_contact].std()) if tr_contact.size > 1 else 1.0
    model = StiffnessCNN(
        X.shape[1],
        n_classes,
        cfg.width,
        cfg.n_blocks,
        cfg.kernel_size,
        cfg.dropout,
        mu,
        max(sd, 1e-3),
    )
    opt = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=cfg.max_epochs)
    ce = nn.CrossEntropyLoss(weight=_class_weights(label[tr], n_classes, cfg.class_weight))
    Xt, yt, lbt = torch.from_numpy(X), torch.from_numpy(label), torch.from_numpy(log_beta)

    best, best_epoch, best_state, history = np.inf, 0, copy.deepcopy(model.state_dict()), []
    t0 = time.perf_counter()
    epoch = 0
    for epoch in range(1, cfg.max_epochs + 1):
        data = (Xt, yt, lbt, ce, cfg.beta_loss_weight)
        train_loss = _train_epoch(model, opt, rng.permutation(tr), cfg.batch_size, data)
        sched.step()
        val_loss = _validation_loss(model, va, data) if va.size else train_loss
        history.append({"epoch": epoch, "train_loss": train_loss, "val_loss": val_loss})
        if on_epoch:
            on_epoch(history[-1])
        if val_loss < best:
            best, best_epoch, best_state = val_loss, epoch, copy.deepcopy(model.state_dict())
        if progress:
            progress(f"epoch {epoch}: train {train_loss:.4f}, val {val_loss:.4f}")
        if epoch - best_epoch >= cfg.patience:
            break
        limit = cfg.max_train_seconds
        if limit is not None and time.perf_counter() - t0 > limit:
            if progress:
                progress(f"time limit {cfg.max_train_seconds:g} s reached")
            break
    model.load_state_dict(best_state)
    model.eval()
    return FitResult(model, best_epoch, epoch, time.perf_counter() - t0, history)


def predict_cnn_outputs(
    model: StiffnessCNN, X: np.ndarray, batch_size: int = 256
) -> dict[str, np.ndarray]:
    """Every output of the exported graph (float32, eval mode), by its ONNX name.

    ``probabilities`` ``(n, n_classes)``, ``log_beta`` and ``log_beta_scale``
    ``(n,)``, ``embedding`` ``(n, width)``.
    """
    model.eval()
    wrapper = ProbabilityModel(model).eval()
    names = ("probabilities", "log_beta", "log_beta_scale", "embedding")
    parts: dict[str, list[np.ndarray]] = {k: [] for k in names}
    with torch.no_grad():
        for i in range(0, len(X), batch_size):
            outs = wrapper(torch.from_numpy(np.ascontiguousarray(X[i : i + batch_size])))
            for k, v in zip(names, outs, strict=True):
                parts[k].append(v.numpy()[:, 0] if v.shape[1] == 1 and k != "probabilities"
                                else v.numpy())  # fmt: skip
    if not parts["probabilities"]:
        return {k: np.empty((0,), np.float32) for k in names}
    return {k: np.concatenate(v) for k, v in parts.items()}


def predict_cnn(
    model: nn.Module, X: np.ndarray, batch_size: int = 256
) -> tuple[np.ndarray, np.ndarray]:
    """Softmax probabilities ``(n, n_classes)`` and log(beta) ``(n,)`` (float32, eval mode)."""
    if len(X) == 0:
        return np.empty((0, 0), np.float32), np.empty(0, np.float32)
    out = predict_cnn_outputs(model, X, batch_size)
    return out["probabilities"], out["log_beta"]
