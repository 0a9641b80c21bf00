"""What the fleet accepts as a unit's name, and how it shows a fleet's location.

A unit's name (serial number) is 1-64 characters: Unicode letters, marks, digits,
punctuation and symbols (categories L, M, N, P, S) and the ASCII space, not at either end.
Refused: control and format characters (a newline forges a row in `list`, an escape
sequence reaches the terminal, a NUL makes a unit the CLI cannot name), other spaces and
separators (they look like a space and are not one), longer names. `check_unit_name` is the
one place that says so, for every command that takes a name and for the store itself.
"""

from __future__ import annotations

import unicodedata
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

from fogsf.errors import UserError

MAX_UNIT_NAME = 64
ALLOWED_CATEGORIES = ("L", "M", "N", "P", "S")  # first letter of unicodedata.category
NAME_RULE = (f"1-{MAX_UNIT_NAME} letters, digits, punctuation, symbols and spaces inside "
             "(no control characters)")


def shown(text: str, limit: int = 40) -> str:
    """A user string safe to print in one line: non-printable characters as escapes
    (repr's), cut at `limit` characters (a 10 kB name must not flood the message)."""
    out = repr(text[:limit])
    return out + ("..." if len(text) > limit else "")


def check_unit_name(name: object) -> str:
    """`name` if it is an acceptable unit name, else a UserError saying which rule it breaks
    (the name shown escaped: it may hold the very characters refused)."""
    if not isinstance(name, str) or not name:
        raise UserError("a unit needs a name (its serial number)")
    if len(name) > MAX_UNIT_NAME:
        raise UserError(f"unit name {shown(name)} is {len(name)} characters long: at most "
                        f"{MAX_UNIT_NAME}")
    for i, ch in enumerate(name):
        if ch == " ":
            if i in (0, len(name) - 1):
                raise UserError(f"unit name {shown(name)} starts or ends with a space")
            continue
        if unicodedata.category(ch)[0] not in ALLOWED_CATEGORIES:
            raise UserError(f"unit name {shown(name)}: character {i + 1} (U+{ord(ch):04X}) "
                            f"is not allowed: {NAME_RULE}")
    return name


# Query parameters of a libpq URL that carry a secret: masked like the URL's password.
SECRET_PARAMS = ("password", "sslpassword")


def masked(location: str, drop: bool = False) -> str:
    """A fleet's location as the CLI prints it: a URL's password (in its user part or its
    query) replaced by ***, or with `drop` left out (a command to run again, the password
    then from PGPASSWORD or ~/.pgpass); a file path unchanged. Never print a fleet URL
    without it."""
    if "://" not in location:
        return location
    try:
        parts = urlsplit(location)
    except ValueError:  # not a URL we can take apart: show its scheme only
        return location.split("://", 1)[0] + "://***"
    netloc = parts.netloc
    user, at, host = netloc.rpartition("@")
    if at and ":" in user:
        name = user.split(":", 1)[0]
        netloc = f"{name}@{host}" if drop else f"{name}:***@{host}"
    query = parts.query
    if query:
        pairs = parse_qsl(query, keep_blank_values=True)
        if any(k in SECRET_PARAMS for k, _ in pairs):
            query = urlencode([(k, v) for k, v in pairs if k not in SECRET_PARAMS] if drop
                              else [(k, "***" if k in SECRET_PARAMS else v) for k, v in pairs],
                              safe="/*")
    return urlunsplit(parts._replace(netloc=netloc, query=query))
