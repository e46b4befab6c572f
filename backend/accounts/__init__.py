"""Accounts: sign-in (lockout, bounded password hashing), sessions (revocation), users."""
