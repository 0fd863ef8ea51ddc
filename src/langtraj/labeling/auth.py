"""Users, passwords (Argon2id through argon2-cffi) and login sessions with their CSRF tokens.

A session cookie carries a random token; the database keeps only its SHA-256, so a leaked database opens
no session. Every write must echo the session's CSRF token in the X-CSRF-Token header. See docs/labeling.md
('Users and security').
"""

from __future__ import annotations

import hashlib
import re
import secrets
from dataclasses import dataclass
from datetime import timedelta

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError
from sqlalchemy import delete, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from langtraj.errors import InputError
from langtraj.labeling.db import utcnow
from langtraj.labeling.models import LoginSession, Role, User

SESSION_LIFETIME = timedelta(hours=12)
MIN_PASSWORD = 8
NAME_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,64}")

_hasher = PasswordHasher()
_DUMMY_HASH = _hasher.hash("not a password of anyone")


@dataclass(frozen=True)
class Identity:
    """Who a request comes from (a snapshot, safe to use after its database session closed)."""

    id: int
    name: str
    role: Role
    csrf: str

    def may(self, *roles: Role) -> bool:
        return self.role in roles


def parse_role(text: str) -> Role:
    try:
        return Role(text)
    except ValueError:
        raise InputError(f"unknown role {text!r}; known: {', '.join(r.value for r in Role)}", where="role") from None


def create_user(session: Session, name: str, password: str, role: Role) -> User:
    """A new user; a bad or taken name or a short password raises InputError."""
    if not NAME_PATTERN.fullmatch(name):
        raise InputError(f"user name {name!r} must be 1-64 letters, digits or . _ -", where="name")
    if len(password) < MIN_PASSWORD:
        raise InputError(f"password must have at least {MIN_PASSWORD} characters", where="password")
    user = User(name=name, role=Role(role).value, password_hash=_hasher.hash(password), created_at=utcnow())
    session.add(user)
    try:
        session.flush()
    except IntegrityError:
        raise InputError(f"user {name!r} exists already", where="name") from None
    return user


def authenticate(session: Session, name: str, password: str) -> User | None:
    """The user when the password is right, else None (a missing user costs the same hashing time)."""
    user = session.scalar(select(User).where(User.name == name))
    try:
        _hasher.verify(user.password_hash if user else _DUMMY_HASH, password)
    except (VerificationError, InvalidHashError):
        return None
    return user


def _digest(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def open_session(session: Session, user: User) -> tuple[str, Identity]:
    """A new login session: (cookie token, identity with its CSRF token)."""
    token, csrf = secrets.token_urlsafe(32), secrets.token_urlsafe(32)
    session.add(
        LoginSession(token_hash=_digest(token), user_id=user.id, csrf=csrf, expires_at=utcnow() + SESSION_LIFETIME)
    )
    return token, Identity(user.id, user.name, Role(user.role), csrf)


def identify(session: Session, token: str | None) -> Identity | None:
    """Who holds session cookie `token`; None when it is missing, unknown or expired."""
    if not token:
        return None
    row = session.get(LoginSession, _digest(token))
    if row is None or row.expires_at < utcnow():
        return None
    return Identity(row.user.id, row.user.name, Role(row.user.role), row.csrf)


def close_session(session: Session, token: str) -> None:
    session.execute(delete(LoginSession).where(LoginSession.token_hash == _digest(token)))


def csrf_matches(identity: Identity, header: str | None) -> bool:
    return header is not None and secrets.compare_digest(identity.csrf, header)
