"""LangTraj: language-conditioned, closed-loop multi-agent traffic simulation."""

__version__ = "0.1.0"
