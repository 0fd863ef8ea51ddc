"""Peak GPU memory of one training step of a preset, measured on this machine's CPU (docs/benchmarks.md,
'Training memory (issue 28, 2026-11-26)').

One step is what `LangTrajModule` computes for a batch (`objective`: the denoising loss, or Algorithm 1's
closed-loop loss, with the text encoder and LoRA when the preset uses text), then backward, gradient
clipping and the AdamW step. It runs at small batch sizes (`--batches`) on synthetic scenes of the
preset's full size (every agent and map slot filled: an upper bound for padded real data), while every
tensor the step creates is counted from its allocation to its release. The live bytes' peak, and the
activations saved for backward by part of the model, are fitted linearly in the batch size and
evaluated at the preset's batch (per GPU: `batch_size` is per process under DDP). Parameters,
gradients and AdamW's two fp32 moments are counted exactly.

Mixed precision ('bf16-mixed'; '16-mixed' counts the same bytes) runs under CPU autocast with CUDA's
casting policy: CUDA autocast runs LayerNorm and softmax in fp32 where CPU autocast keeps bf16, so those
calls get fp32 inputs here as on a GPU (`cuda_float32_policy`).

The last line is `peak GiB: X`: the step's peak times ALLOWANCE_FACTOR plus ALLOWANCE_GIB, for the CUDA
context and the caching allocator's rounding and fragmentation.

    python benchmarks/train_memory.py --config configs/base.yaml [--batches 1 2] [--precision bf16-mixed]
"""

from __future__ import annotations

import argparse
import weakref
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import torch
from synthetic import synthetic_batch
from torch import Tensor, nn
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils._pytree import tree_flatten, tree_map

GIB = 2**30

ALLOWANCE_FACTOR = 1.15
"""Peak bytes -> GPU memory: the caching allocator rounds blocks up and fragments (docs/benchmarks.md)."""

ALLOWANCE_GIB = 1.0
"""GiB added for the CUDA context and kernel images, which no tensor counts (0.5 to 1 GiB)."""

MIXED_PRECISIONS = ("bf16-mixed", "16-mixed")
"""Lightning precisions that autocast to 2-byte floats; both are measured under bf16 (same bytes)."""

FULL_PRECISIONS = ("32-true", "32")

CUDA_FLOAT32_FUNCTIONS: tuple[tuple[Any, str], ...] = (
    (torch.nn.functional, "layer_norm"),
    (torch.nn.functional, "group_norm"),
    (torch.nn.functional, "softmax"),
    (torch.nn.functional, "log_softmax"),
    (torch, "softmax"),
    (torch, "log_softmax"),
    (torch.Tensor, "softmax"),
    (torch.Tensor, "log_softmax"),
)
"""Functions the model calls on 2-byte floats that CUDA autocast runs in fp32 (on its 'float32' list) and CPU
autocast leaves in bf16. The list's other entries (sum, exp, pow, ...) meet only fp32 tensors here."""

PARTS: tuple[tuple[str, str], ...] = (
    ("model.encoder.map_layers", "scene encoder: map attention"),
    ("model.encoder.agent_layers", "scene encoder: agent attention"),
    ("model.encoder", "scene encoder: embeddings"),
    ("model.denoiser.blocks", "denoiser: attention blocks"),
    ("model.denoiser", "denoiser: embeddings, output"),
    ("model.text_encoder", "text encoder (LoRA)"),
)
"""Module prefixes whose saved activations are reported apart, first match wins; the rest is 'other'."""

OTHER = "other (loss, dynamics, fusion)"


# ---------------------------------------------------------------------------------------------- counting


class LiveBytes(TorchDispatchMode):
    """Counts the bytes of every tensor storage that an op creates while the mode is on, until the storage
    is freed: `live` now and the `peak` of `live` (what `torch.cuda.max_memory_allocated` gives on a GPU,
    without the allocator's rounding)."""

    def __init__(self) -> None:
        super().__init__()
        self.sizes: dict[int, int] = {}
        self.live = 0
        self.peak = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        out = func(*args, **(kwargs or {}))
        for value in tree_flatten(out)[0]:
            if isinstance(value, Tensor) and value.device.type == "cpu":
                self._track(value.untyped_storage())
        return out

    def _track(self, storage: torch.UntypedStorage) -> None:
        key = id(storage)
        if key in self.sizes or storage.nbytes() == 0:
            return
        self.sizes[key] = storage.nbytes()
        self.live += storage.nbytes()
        self.peak = max(self.peak, self.live)
        weakref.finalize(storage, self._free, key)

    def _free(self, key: int) -> None:
        self.live -= self.sizes.pop(key, 0)

    def knows(self, tensor: Tensor) -> bool:
        """Whether the step created `tensor`'s storage (parameters and the batch were there before)."""
        return id(tensor.untyped_storage()) in self.sizes


@contextmanager
def cuda_float32_policy() -> Iterator[None]:
    """Under CPU autocast, CUDA_FLOAT32_FUNCTIONS get fp32 inputs, as CUDA autocast gives them (it casts their
    2-byte inputs to fp32), so their outputs and saved inputs take a GPU's bytes. The functions are replaced
    for the duration (a torch function mode would not reach the recomputation of checkpointed blocks, which
    runs inside backward)."""
    originals = [(owner, name, getattr(owner, name)) for owner, name in CUDA_FLOAT32_FUNCTIONS]
    for owner, name, function in originals:
        setattr(owner, name, _in_float32(function))
    try:
        yield
    finally:
        for owner, name, function in originals:
            setattr(owner, name, function)


def _in_float32(function: Callable[..., Any]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if torch.is_autocast_enabled("cpu"):
            args, kwargs = tree_map(_to_float32, (args, kwargs))
        return function(*args, **kwargs)

    return wrapper


def _to_float32(value: Any) -> Any:
    if isinstance(value, Tensor) and value.dtype in (torch.bfloat16, torch.float16):
        return value.float()
    return value


@dataclass
class SavedActivations:
    """Storages saved for backward during the forward pass, each credited to the part of the model that
    saved it first (PARTS, by the innermost running module)."""

    live: LiveBytes
    modules: list[str] = field(default_factory=list)
    storages: dict[int, tuple[str, weakref.ref]] = field(default_factory=dict)

    def pack(self, tensor: Tensor) -> Tensor:
        if self.live.knows(tensor):
            storage = tensor.untyped_storage()
            part = _part(self.modules[-1] if self.modules else "")
            self.storages.setdefault(id(storage), (part, weakref.ref(storage)))
        return tensor

    def by_part(self) -> dict[str, int]:
        """Bytes of the saved storages still alive, per part."""
        out: dict[str, int] = {}
        for part, ref in self.storages.values():
            storage = ref()
            if storage is not None:
                out[part] = out.get(part, 0) + storage.nbytes()
        return out

    def _enter(self, name: str) -> Callable[..., None]:
        def hook(*_: Any) -> None:
            self.modules.append(name)

        return hook

    def _leave(self, *_: Any) -> None:
        self.modules.pop()

    @contextmanager
    def watching(self, model: nn.Module) -> Iterator[None]:
        """Saved tensors are credited to the module running when they are saved."""
        handles = []
        for name, module in model.named_modules():
            handles.append(module.register_forward_pre_hook(self._enter(name)))
            handles.append(module.register_forward_hook(self._leave))
        try:
            with torch.autograd.graph.saved_tensors_hooks(self.pack, lambda tensor: tensor):
                yield
        finally:
            for handle in handles:
                handle.remove()


def _part(module: str) -> str:
    for prefix, label in PARTS:
        if module == prefix or module.startswith(prefix + "."):
            return label
    return OTHER


# ---------------------------------------------------------------------------------------------- the step


def tensor_bytes(values: Sequence[Any]) -> int:
    return sum(v.numel() * v.element_size() for v in values if isinstance(v, Tensor))


@dataclass
class Static:
    """Bytes that do not depend on the batch: every parameter (frozen text weights included), the
    gradients of the trainable ones and AdamW's two fp32 moments per trainable parameter."""

    parameters: int
    trainable: int
    gradients: int
    optimizer: int


class Step:
    """One training step of a preset on the CPU, as Lightning runs it on a GPU: the module's objective
    (under autocast for mixed precision), backward, gradient-norm clipping, AdamW with its GPU default
    (foreach) and the scheduler."""

    def __init__(self, config, mixed: bool):
        from langtraj.training.module import LangTrajModule

        torch.manual_seed(config.seed)
        self.config, self.mixed = config, mixed
        self.module = LangTrajModule(config.to_dict()).train()
        setup = self.module.configure_optimizers()
        self.optimizer, self.scheduler = setup["optimizer"], setup["lr_scheduler"]["scheduler"]
        for group in self.optimizer.param_groups:
            group["foreach"] = True  # what AdamW picks for CUDA parameters
        self.params = [p for group in self.optimizer.param_groups for p in group["params"]]
        for p in self.params:  # gradients and optimizer state exist from the first step on
            p.grad = torch.zeros_like(p)
        self.optimizer.step()
        self.optimizer.zero_grad(set_to_none=False)

    def static(self) -> Static:
        state = [v for s in self.optimizer.state.values() for v in s.values()]
        return Static(
            parameters=tensor_bytes(list(self.module.parameters())),
            trainable=sum(p.numel() for p in self.params),
            gradients=tensor_bytes([p.grad for p in self.params]),
            optimizer=tensor_bytes(state),
        )

    def measure(self, batch_size: int) -> dict[str, int]:
        """Bytes of one step at `batch_size`: 'peak' of the live tensors the step creates, 'saved' at the end
        of the forward pass (the activations kept for backward) and the saved bytes of each part."""
        batch = synthetic_batch(self.config, batch_size, seed=batch_size)
        torch.manual_seed(batch_size)
        live = LiveBytes()
        saved = SavedActivations(live)
        with ExitStack() as step:
            step.enter_context(live)
            if self.mixed:  # also while backward recomputes checkpointed blocks (under their saved autocast)
                step.enter_context(cuda_float32_policy())
            with ExitStack() as forward:
                forward.enter_context(saved.watching(self.module))
                if self.mixed:
                    forward.enter_context(torch.autocast("cpu", dtype=torch.bfloat16))
                loss = self.module.objective(batch)["loss"]
            parts = saved.by_part()
            loss.backward()
            del loss
            if self.config.optim.grad_clip > 0:
                torch.nn.utils.clip_grad_norm_(self.params, self.config.optim.grad_clip, foreach=True)
            self.optimizer.step()
            self.scheduler.step()
            self.optimizer.zero_grad(set_to_none=False)
        return {"peak": live.peak, "saved": sum(parts.values()), **{f"saved:{k}": v for k, v in parts.items()}}


# ---------------------------------------------------------------------------------------------- the estimate


def fit(batches: Sequence[int], values: Sequence[float]) -> tuple[float, float]:
    """(intercept, slope) of the least-squares line through (batch, value); one batch: through zero."""
    if len(batches) == 1:
        return 0.0, values[0] / batches[0]
    n = len(batches)
    mean_b, mean_v = sum(batches) / n, sum(values) / n
    slope = sum((b - mean_b) * (v - mean_v) for b, v in zip(batches, values, strict=True)) / sum(
        (b - mean_b) ** 2 for b in batches
    )
    return mean_v - slope * mean_b, slope


@dataclass
class Estimate:
    """GiB of each component at the preset's batch, in table order, and the peak with its allowance."""

    rows: list[tuple[str, float]]
    total: float

    @property
    def peak(self) -> float:
        return self.total * ALLOWANCE_FACTOR + ALLOWANCE_GIB


def estimate(config, static: Static, measured: dict[int, dict[str, int]], ddp: bool) -> Estimate:
    """Components at `config.batch_size`: static bytes exactly, the batch's tensors per scene, and the
    saved activations (by part) and the rest of the step's peak fitted linearly in the batch size."""
    batches = sorted(measured)
    at = config.batch_size

    def line(key: str) -> float:
        intercept, slope = fit(batches, [measured[b].get(key, 0) for b in batches])
        return max(intercept + slope * at, 0.0) / GIB

    batch_gib = tensor_bytes(list(vars(synthetic_batch(config, 1)).values())) * at / GIB
    rows = [
        ("parameters (fp32)", static.parameters / GIB),
        ("gradients (fp32)", static.gradients / GIB),
        ("AdamW state (2 x fp32)", static.optimizer / GIB),
    ]
    if ddp:
        rows.append(("DDP gradient buckets", static.gradients / GIB))
    rows.append(("batch tensors", batch_gib))
    seen = {k.split(":", 1)[1] for b in batches for k in measured[b] if k.startswith("saved:")}
    parts = [part for part in [label for _, label in PARTS] + [OTHER] if part in seen]
    saved = {part: line(f"saved:{part}") for part in parts}
    peak = line("peak")
    rows += [(f"saved for backward: {part}", gib) for part, gib in saved.items()]
    rows.append(("the rest of the peak: recomputed blocks, backward, AdamW", max(peak - sum(saved.values()), 0.0)))
    return Estimate(rows, sum(gib for _, gib in rows))


def precision_is_mixed(precision: str) -> bool:
    if precision in MIXED_PRECISIONS:
        return True
    if precision in FULL_PRECISIONS:
        return False
    raise SystemExit(f"precision {precision!r}: this benchmark knows {', '.join(MIXED_PRECISIONS + FULL_PRECISIONS)}")


def run(config_path: Path, batches: Sequence[int], precision: str | None, say: Callable[[str], None] = print) -> float:
    """Print the component table of `config_path`'s step and return its peak GiB (with the allowance)."""
    from langtraj.training.config import load_config

    config = load_config(config_path)
    if precision is not None:
        config = replace(config, precision=precision)
    mixed = precision_is_mixed(config.precision)
    ddp = config.strategy.startswith("ddp")
    step = Step(config, mixed)
    static = step.static()
    measured = {b: step.measure(b) for b in sorted(set(batches))}
    result = estimate(config, static, measured, ddp)
    model = config.model
    counted = " (counted as bf16-mixed: the same bytes)" if config.precision == "16-mixed" else ""
    say(
        f"preset {config_path}: {static.trainable / 1e6:.2f} M trainable parameters, {config.data.max_agents} agents, "
        f"{config.data.max_polylines} map pieces of {config.data.points_per_polyline} points, batch {config.batch_size}"
        f"{' per GPU (DDP)' if ddp else ''}, precision {config.precision}{counted}, objective {config.objective}, "
        f"text {'on' if model.use_text else 'off'}, gradient checkpointing "
        f"{'on' if model.gradient_checkpointing else 'off'}"
    )
    say(
        "measured on the CPU: step peak "
        + ", ".join(f"{measured[b]['peak'] / GIB:.3f} GiB at batch {b}" for b in sorted(measured))
        + f"; extrapolated linearly to batch {config.batch_size}"
    )
    width = max(len(name) for name, _ in result.rows) + 2
    say(f"{'component':<{width}}GiB")
    for name, gib in result.rows:
        say(f"{name:<{width}}{gib:.2f}")
    say(f"{'total':<{width}}{result.total:.2f}")
    say(
        f"allowance: x {ALLOWANCE_FACTOR} + {ALLOWANCE_GIB} GiB for the CUDA context and the caching allocator's "
        "rounding and fragmentation"
    )
    say(f"peak GiB: {result.peak:.2f}")
    return result.peak


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", required=True, type=Path, help="a training preset (configs/*.yaml)")
    parser.add_argument("--batches", nargs="+", type=int, default=[1, 2], help="batch sizes measured on the CPU")
    parser.add_argument("--precision", help="override the preset's precision (32-true, bf16-mixed, 16-mixed)")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (the figures do not depend on it)")
    args = parser.parse_args(argv)
    if min(args.batches) < 1:
        parser.error("batch sizes must be >= 1")
    torch.set_num_threads(args.threads)
    run(args.config, args.batches, args.precision)


if __name__ == "__main__":
    main()
