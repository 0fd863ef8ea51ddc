"""The registry behind every extension point."""

from __future__ import annotations

import pytest

from langtraj.errors import InputError
from langtraj.registry import Registry


class Base:
    name = "base"


def test_register_create_and_list_in_order():
    loads = []
    registry: Registry[Base] = Registry("widget", loader=lambda: loads.append(1))

    @registry.register
    class B(Base):
        name = "b"

    @registry.register
    class A(Base):
        name = "a"

    assert registry.names() == ("b", "a")
    assert isinstance(registry.create("a"), A)
    assert registry.classes() == (B, A)
    assert loads == [1]  # the loader runs once, before the first lookup


def test_unknown_name_lists_the_known_and_says_where():
    registry: Registry[Base] = Registry("widget")
    registry.register(type("W", (Base,), {"name": "w"}))
    with pytest.raises(InputError, match=r"--thing: unknown widget 'x'; known: w"):
        registry.create("x", where="--thing")


def test_two_classes_under_one_name_are_refused():
    registry: Registry[Base] = Registry("widget")
    registry.register(type("One", (Base,), {"name": "same"}))
    with pytest.raises(ValueError, match="widget 'same' is already registered"):
        registry.register(type("Two", (Base,), {"name": "same"}))
