"""What every file download's response says about its file."""

from __future__ import annotations

from urllib.parse import quote


def attachment(filename: str) -> str:
    """Content-Disposition for any name: an ASCII stand-in in `filename` (quotes, backslashes,
    control and non-ASCII characters replaced) and the exact name in RFC 5987 `filename*`."""
    fallback = "".join(c if " " <= c <= "~" and c not in '"\\' else "_" for c in filename)
    return f"attachment; filename=\"{fallback}\"; filename*=UTF-8''{quote(filename, safe='')}"
