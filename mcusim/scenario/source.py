"""Where things are in a scenario's source text: tomllib gives no positions, so :class:`_Lines`
finds the line of every table header and key by scanning the text (``_scan`` follows values that
continue over several lines: multi-line strings, arrays, inline tables)."""

from __future__ import annotations

import json
import re

_BARE = r"[A-Za-z0-9_-]+"
_BASIC = r'"(?:[^"\\\n]|\\.)*"'
_LITERAL = r"'[^'\n]*'"
_KEY = rf"(?:{_BARE}|{_BASIC}|{_LITERAL})"
_KEYPATH = rf"{_KEY}(?:\s*\.\s*{_KEY})*"
_KEY_RE = re.compile(rf"\s*({_KEYPATH})\s*=")
_ARRAY_RE = re.compile(rf"\s*\[\[\s*({_KEYPATH})\s*\]\]")
_TABLE_RE = re.compile(rf"\s*\[\s*({_KEYPATH})\s*\]")


def _keypath(text: str) -> tuple:
    out = []
    for tok in re.findall(_KEY, text):
        if tok.startswith('"'):
            try:
                tok = json.loads(tok)
            except ValueError:
                tok = tok[1:-1]
        elif tok.startswith("'"):
            tok = tok[1:-1]
        out.append(tok)
    return tuple(out)


def _scan(s: str, i: int, delim, depth: int):
    """Follow a value from ``s[i]`` to the end of the line: (open multi-line string delimiter or
    None, bracket depth), so that the next lines are known to continue it."""
    n = len(s)
    while i < n:
        if delim:
            j = s.find(delim, i)
            if j < 0:
                return delim, depth
            i, delim = j + 3, None
            continue
        c = s[i]
        if c == "#":
            break
        if s.startswith('"""', i) or s.startswith("'''", i):
            delim, i = s[i:i + 3], i + 3
        elif c == '"':
            i += 1
            while i < n and s[i] != '"':
                i += 2 if s[i] == "\\" else 1
            i += 1
        elif c == "'":
            j = s.find("'", i + 1)
            i = j + 1 if j >= 0 else n
        else:
            depth += (c in "[{") - (c in "]}")
            i += 1
    return delim, max(depth, 0)


class _Lines:
    """Line numbers of table headers and keys. A context is (table, index): ``("at", 2)`` is the
    third ``[[at]]``, ``("set", None)`` the ``[set]`` table, ``(None, None)`` the top level; keys
    are tuples (``("fault", "kind")``, ``("motor1.load_inertia",)``)."""

    def __init__(self, text: str):
        self.tables: dict = {}
        self.keys: dict = {}
        count: dict = {}
        ctx, prefix = (None, None), ()
        delim, depth = None, 0
        for no, raw in enumerate(text.splitlines(), start=1):
            if delim or depth:
                delim, depth = _scan(raw, 0, delim, depth)
                continue
            m = _ARRAY_RE.match(raw)
            if m:
                path = _keypath(m.group(1))
                if len(path) == 1:
                    count[path[0]] = count.get(path[0], 0) + 1
                    ctx, prefix = (path[0], count[path[0]] - 1), ()
                    self.tables.setdefault(ctx, no)
                else:
                    ctx, prefix = (path[0], count[path[0]] - 1 if path[0] in count else None), path[1:]
                    self._key(ctx, prefix, no)
                continue
            m = _TABLE_RE.match(raw)
            if m:
                path = _keypath(m.group(1))
                ctx = (path[0], count[path[0]] - 1 if path[0] in count else None)
                prefix = path[1:]
                if prefix:
                    self._key(ctx, prefix, no)
                else:
                    self.tables.setdefault(ctx, no)
                continue
            m = _KEY_RE.match(raw)
            if m:
                self._key(ctx, prefix + _keypath(m.group(1)), no)
                delim, depth = _scan(raw, m.end(), None, 0)

    def _key(self, ctx, path, no):
        keys = self.keys.setdefault(ctx, {})
        for k in range(1, len(path) + 1):
            keys.setdefault(path[:k], no)

    def _search(self, ctx, key: tuple):
        keys = self.keys.get(ctx, {})
        for n in range(len(key), 0, -1):
            if key[:n] in keys:
                return keys[key[:n]]
        return None

    def line(self, table=None, index=None, key=()) -> int:
        """The line of ``key`` in the table (or of the longest part of it that is found), else of
        the table's header, else of the top-level key that defines the table, else 1. With no
        table, ``key[0]`` may name a table (``[scenaro]``): its header line."""
        key = tuple(key)
        if table is None:
            if key:
                for ctx in ((key[0], None), (key[0], 0)):
                    if ctx in self.tables or ctx in self.keys:
                        return self.line(key[0], ctx[1], key[1:])
            return self._search((None, None), key) or 1
        found = self._search((table, index), key)
        if found is None:
            found = self.tables.get((table, index))
        if found is None and self.keys.get((table, index)):     # only dotted headers: [run.set]
            found = min(self.keys[(table, index)].values())
        if found is None:
            found = self._search((None, None), (table,) + key)
        return found or self.tables.get((table, None)) or self.tables.get((table, 0)) or 1
