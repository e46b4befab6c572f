"""Password hashes for test users, made once per test process.

An argon2 hash with the product's parameters (3 passes over 64 MiB) costs about 0.3 s of CPU,
more on a loaded machine, and the fixtures add users in most backend tests. A hash stays valid
for its password whatever the salt, so each test password is hashed once and the hash reused;
every sign-in still verifies it with the product's own code."""

from __future__ import annotations

from functools import cache

from backend.security import hash_password


@cache
def password_hash(password: str) -> str:
    """`hash_password(password)`, computed on the first call for this password only."""
    return hash_password(password)
