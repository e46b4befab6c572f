"""Password hashing (argon2), signed browser access tokens, robot token hashing."""

from __future__ import annotations

import base64
import hashlib
import hmac
import json
import secrets
import time

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

_hasher = PasswordHasher()


def hash_password(password: str) -> str:
    return _hasher.hash(password)


def verify_password(password_hash: str, password: str) -> bool:
    try:
        return _hasher.verify(password_hash, password)
    except (VerificationError, InvalidHashError):
        return False


def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode()


def _unb64(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))


def create_access_token(secret_key: str, user_id: int, minutes: int) -> str:
    payload = _b64(json.dumps({"sub": user_id, "exp": int(time.time()) + minutes * 60}).encode())
    signature = _b64(hmac.new(secret_key.encode(), payload.encode(), hashlib.sha256).digest())
    return f"{payload}.{signature}"


def read_access_token(secret_key: str, token: str) -> int | None:
    """The user id of a valid, unexpired token; None otherwise."""
    payload, _, signature = token.partition(".")
    expected = _b64(hmac.new(secret_key.encode(), payload.encode(), hashlib.sha256).digest())
    if not signature or not hmac.compare_digest(signature, expected):
        return None
    try:
        claims = json.loads(_unb64(payload))
    except ValueError:
        return None
    if not isinstance(claims, dict) or claims.get("exp", 0) < time.time():
        return None
    sub = claims.get("sub")
    return sub if isinstance(sub, int) else None


def new_robot_token() -> str:
    return secrets.token_urlsafe(32)


def hash_robot_token(token: str) -> str:
    # Robot tokens are 256-bit random secrets: a plain SHA-256 is enough (no dictionary to
    # guess from) and keeps the per-connection check cheap.
    return hashlib.sha256(token.encode()).hexdigest()


def robot_token_matches(token_hash: str | None, token: str) -> bool:
    return token_hash is not None and hmac.compare_digest(token_hash, hash_robot_token(token))
