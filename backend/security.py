"""Password hashing (argon2), signed browser access tokens, robot token hashing."""

from __future__ import annotations

import base64
import hashlib
import hmac
import json
import secrets
import time
from dataclasses import dataclass

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

# One lane (argon2-cffi's default is 4, i.e. 4 threads per verification): a verification then
# takes at most one core, so sign-ins cannot take both cores from robot ingest. Time and memory
# cost stay at the defaults (3 passes over 64 MiB), above OWASP's minimum.
_hasher = PasswordHasher(parallelism=1)


def hash_password(password: str) -> str:
    return _hasher.hash(password)


def verify_password(password_hash: str, password: str) -> bool:
    try:
        return _hasher.verify(password_hash, password)
    except (VerificationError, InvalidHashError):
        return False


def needs_rehash(password_hash: str) -> bool:
    """Whether a stored hash was made with other parameters (e.g. 4 lanes, before)."""
    try:
        return _hasher.check_needs_rehash(password_hash)
    except InvalidHashError:
        return False


_dummy_hash: str | None = None


def verify_password_or_dummy(password_hash: str | None, password: str) -> bool:
    """Verify against `password_hash`, or, for an unknown user (None), against a dummy hash
    made with the same parameters: both cost one argon2 verification, so the answer's timing
    does not tell whether the user exists. Always False for None."""
    global _dummy_hash
    if password_hash is None:
        if _dummy_hash is None:
            _dummy_hash = _hasher.hash(secrets.token_urlsafe(16))
        verify_password(_dummy_hash, password)
        return False
    return verify_password(password_hash, password)


def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode()


def _unb64(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))


@dataclass(frozen=True)
class SessionClaims:
    """What a valid browser token says: whose session, which one (jti), until when."""

    user_id: int
    jti: str
    expires_at: float  # unix time


def create_access_token(secret_key: str, user_id: int, minutes: int) -> str:
    claims = {
        "sub": user_id,
        "jti": secrets.token_urlsafe(16),  # names the session so logout can revoke it alone
        "exp": int(time.time()) + minutes * 60,
    }
    payload = _b64(json.dumps(claims).encode())
    signature = _b64(hmac.new(secret_key.encode(), payload.encode(), hashlib.sha256).digest())
    return f"{payload}.{signature}"


def read_access_claims(secret_key: str, token: str) -> SessionClaims | None:
    """The claims of a validly signed, unexpired token; None otherwise (revocation is checked
    against the database by the caller)."""
    payload, _, signature = token.partition(".")
    expected = _b64(hmac.new(secret_key.encode(), payload.encode(), hashlib.sha256).digest())
    if not signature or not hmac.compare_digest(signature, expected):
        return None
    try:
        claims = json.loads(_unb64(payload))
    except ValueError:
        return None
    if not isinstance(claims, dict):
        return None
    sub, jti, exp = claims.get("sub"), claims.get("jti"), claims.get("exp")
    if not isinstance(sub, int) or not isinstance(jti, str) or not jti:
        return None  # tokens from before revocation existed carry no jti: sign in again
    if not isinstance(exp, int | float) or exp < time.time():
        return None
    return SessionClaims(sub, jti, float(exp))


def read_access_token(secret_key: str, token: str) -> int | None:
    """The user id of a validly signed, unexpired token; None otherwise."""
    claims = read_access_claims(secret_key, token)
    return claims.user_id if claims else None


def new_robot_token() -> str:
    return secrets.token_urlsafe(32)


def hash_robot_token(token: str) -> str:
    # Robot tokens are 256-bit random secrets: a plain SHA-256 is enough (no dictionary to
    # guess from) and keeps the per-connection check cheap.
    return hashlib.sha256(token.encode()).hexdigest()


def robot_token_matches(token_hash: str | None, token: str) -> bool:
    return token_hash is not None and hmac.compare_digest(token_hash, hash_robot_token(token))
