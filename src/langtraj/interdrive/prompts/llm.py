"""Optional LLM rephrasing of phrases through any OpenAI-compatible chat endpoint (off by default).

The paper rephrased its prompts with an LLM; this backend does the same for a phrase ("yields to
<other> at the intersection"), keeps only outputs that preserve its `<slot>` placeholders, and caches
the answers on disk so a rerun makes no request. Standard library only (urllib); no network is used
unless `LLMConfig.url` is set.

See docs/interdrive.md.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import unicodedata
import urllib.error
import urllib.request
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from langtraj.errors import LangTrajError
from langtraj.fileio import atomic_open
from langtraj.interdrive.prompts.phrases import PhraseBank, phrase_tables

_PLACEHOLDER = re.compile(r"<[A-Za-z_][A-Za-z0-9_]*>")
_LIST_MARK = re.compile(r"^\s*(?:[-*•]|\d+[.)])\s*")
_QUOTES = "\"'`“”‘’"


class LLMError(LangTrajError):
    """The LLM backend is off, unreachable, or answered something that is not a chat completion."""


def _default_cache_dir() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "langtraj" / "llm"


@dataclass(frozen=True)
class LLMConfig:
    """Where and how to ask: `url` is the API base (e.g. "http://localhost:8000/v1"; None = off), the key is
    read from the environment variable `api_key_env` (optional for local servers), answers are cached in
    `cache_dir`; `n` rephrasings per phrase by default, each at most `max_chars` long."""

    url: str | None = None
    model: str = "gpt-4o-mini"
    api_key_env: str = "OPENAI_API_KEY"
    cache_dir: Path = field(default_factory=_default_cache_dir)
    timeout_s: float = 60.0
    n: int = 20
    max_chars: int = 200
    temperature: float = 1.0

    def __post_init__(self) -> None:
        if self.timeout_s <= 0 or self.n < 1 or self.max_chars < 1:
            raise ValueError(f"LLMConfig needs timeout_s > 0, n >= 1, max_chars >= 1; got {self}")

    @property
    def enabled(self) -> bool:
        return self.url is not None


def _instructions(n: int) -> str:
    return (
        "You rephrase short descriptions of what a road user does in traffic. Each description is a verb phrase"
        " whose subject is omitted, in the third person singular (e.g. 'slows down and turns left')."
        f" Write {n} different rephrasings with the same meaning, natural English, also verb phrases without a"
        " subject. Keep every placeholder in angle brackets, such as <other>, exactly as written, once each."
        " Answer with one rephrasing per line and nothing else: no numbering, no quotes, no blank lines."
    )


def placeholders(text: str) -> Counter[str]:
    """The `<slot>` placeholders of `text`, with their counts."""
    return Counter(_PLACEHOLDER.findall(text))


def clean_rephrasings(phrase: str, answer: str, n: int, max_chars: int) -> tuple[str, ...]:
    """The valid distinct rephrasings in `answer` (one per line), at most `n`: list marks and quotes
    stripped; lines that are empty, overlong, hold control characters, repeat `phrase`, or lose or add
    placeholders are dropped."""
    wanted = placeholders(phrase)
    out: dict[str, str] = {}
    for raw in answer.splitlines():
        line = _LIST_MARK.sub("", raw).strip().strip(_QUOTES).strip().rstrip(".").strip()
        if not line or len(line) > max_chars or any(unicodedata.category(c).startswith("C") for c in line):
            continue
        if placeholders(line) != wanted or "<" in _PLACEHOLDER.sub("", line) or ">" in _PLACEHOLDER.sub("", line):
            continue
        if line.lower() == phrase.lower():
            continue
        out.setdefault(line.lower(), line)
    return tuple(out.values())[:n]


class LLMRephraser:
    """Rephrases phrases with an OpenAI-compatible `POST {url}/chat/completions`, caching answers on disk."""

    def __init__(self, config: LLMConfig):
        self.config = config

    @property
    def endpoint(self) -> str:
        if self.config.url is None:
            raise LLMError("LLM rephrasing is off: set LLMConfig.url to an OpenAI-compatible API base")
        return self.config.url.rstrip("/") + "/chat/completions"

    def cache_path(self, phrase: str, n: int) -> Path:
        key = json.dumps([self.config.url, self.config.model, phrase, n], ensure_ascii=False)
        return Path(self.config.cache_dir) / f"{hashlib.sha256(key.encode('utf-8')).hexdigest()}.json"

    def rephrase(self, phrase: str, n: int | None = None) -> tuple[str, ...]:
        """Up to `n` (default `config.n`) valid rephrasings of `phrase`, from the cache or the endpoint."""
        n = self.config.n if n is None else n
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        endpoint = self.endpoint
        path = self.cache_path(phrase, n)
        cached = self._read_cache(path)
        if cached is not None:
            return cached
        answer = self._request(endpoint, phrase, n)
        result = clean_rephrasings(phrase, answer, n, self.config.max_chars)
        record = {"url": self.config.url, "model": self.config.model, "phrase": phrase, "n": n, "rephrasings": result}
        with atomic_open(path, "wb") as fh:
            fh.write(json.dumps(record, ensure_ascii=False, indent=1).encode("utf-8"))
        return result

    @staticmethod
    def _read_cache(path: Path) -> tuple[str, ...] | None:
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
            items = record["rephrasings"]
        except (OSError, ValueError, KeyError, TypeError):
            return None  # missing or unreadable: ask again (and overwrite it)
        if not isinstance(items, list) or not all(isinstance(x, str) for x in items):
            return None
        return tuple(items)

    def _request(self, endpoint: str, phrase: str, n: int) -> str:
        body = {
            "model": self.config.model,
            "temperature": self.config.temperature,
            "messages": [
                {"role": "system", "content": _instructions(n)},
                {"role": "user", "content": phrase},
            ],
        }
        headers = {"Content-Type": "application/json"}
        key = os.environ.get(self.config.api_key_env)
        if key:
            headers["Authorization"] = f"Bearer {key}"
        request = urllib.request.Request(endpoint, data=json.dumps(body).encode("utf-8"), headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=self.config.timeout_s) as response:
                payload: Any = json.loads(response.read().decode("utf-8"))
        except urllib.error.HTTPError as exc:
            raise LLMError(f"LLM request to {endpoint} failed: HTTP {exc.code} {exc.reason}") from None
        except urllib.error.URLError as exc:
            raise LLMError(f"LLM request to {endpoint} failed: {exc.reason}") from None
        except (OSError, ValueError) as exc:  # timeouts, resets, bad JSON
            raise LLMError(f"LLM request to {endpoint} failed: {exc}") from None
        try:
            content = payload["choices"][0]["message"]["content"]
        except (KeyError, IndexError, TypeError):
            raise LLMError(f"LLM response from {endpoint} is not a chat completion: {str(payload)[:200]}") from None
        if not isinstance(content, str):
            raise LLMError(f"LLM response from {endpoint} has no text content")
        return content


def llm_phrase_bank(rephraser: LLMRephraser, keys: Iterable[str] | None = None) -> PhraseBank:
    """A phrase bank extending the templates with the LLM's rephrasings of each table's canonical phrase
    (every table, or those of `keys`); answers come from the rephraser's disk cache when present."""
    tables = phrase_tables()
    extra = {}
    for key in keys if keys is not None else tables:
        known = set(tables[key])
        extra[key] = tuple(p for p in rephraser.rephrase(tables[key][0]) if p not in known)
    return PhraseBank(extra)
