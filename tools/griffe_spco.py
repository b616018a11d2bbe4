"""A griffe extension that lets the API reference read spco's docstrings as they are written.

spco's docstrings use numpy section headers (``Parameters`` underlined with dashes) with items
written ``name: description`` — one line per parameter, continued on lines indented by four
spaces — and Sphinx cross-reference roles (``:class:`~spco.data.Corpus```). The numpy parser of
griffe (which mkdocstrings uses) expects ``name : type`` with the description on the next lines,
and shows roles as they are. Before a docstring is parsed, this extension rewrites

- an item ``name: description`` of a ``Parameters``, ``Other Parameters`` or ``Attributes``
  section into ``name`` followed by the description, indented (several items on one line,
  ``a: …; b: …``, are split when ``b`` is a parameter of the function, and ``a, b: …`` becomes
  one entry per name, each with its own type); a line of such a section
  that is not an item continues the item above it, and a paragraph after a blank line that is not
  an item opens a ``Notes`` section (prose about the parameters as a whole);
- a ``Returns`` section written as prose into the function's return annotation followed by that
  prose, indented;
- a role ``:class:`~a.b.C``` (``:func:``, ``:meth:``, ``:mod:``, ``:data:``, ``:attr:``,
  ``:exc:``, ``:obj:``) into inline code, ``C`` (the last part with ``~``, the whole target
  otherwise).

mkdocs.yml loads it: ``extensions: [tools/griffe_spco.py:SpcoDocstrings]``.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj|const):`(~?)([^`]+)`")
_ITEM = re.compile(r"^(\*{0,2}[A-Za-z_]\w*(?:,\s*\*{0,2}[A-Za-z_]\w*)*):(?:\s+(\S.*))?$")
_ITEM_SECTIONS = {"parameters", "other parameters", "attributes"}


def _role(match: re.Match[str]) -> str:
    target = match.group(2)
    return f"`{target.rsplit('.', 1)[-1] if match.group(1) else target}`"


def _sections(lines: list[str]) -> list[tuple[str, int, int]]:
    """(title, first line of the body, end) of every numpy section: a title underlined by dashes."""
    starts = [(lines[i].strip().lower(), i + 2) for i in range(len(lines) - 1)
              if lines[i].strip() and re.fullmatch(r"-{3,}", lines[i + 1].strip())
              and not lines[i].startswith(" ")]
    return [(title, body, (starts[k + 1][1] - 2) if k + 1 < len(starts) else len(lines))
            for k, (title, body) in enumerate(starts)]


def _items(lines: list[str], parameters: set[str]) -> list[str]:
    """The body of an item section (see the module docstring)."""
    out: list[str] = []

    def is_item(text: str) -> re.Match[str] | None:
        match = _ITEM.match(text)
        names = [] if match is None else [n.strip().lstrip("*") for n in match.group(1).split(",")]
        return match if match is not None and (not parameters or set(names) <= parameters) else None

    for k, line in enumerate(lines):
        if not line.strip() or line.startswith(" "):
            out.append(line)
            continue
        if is_item(line) is None and k > 0 and not lines[k - 1].strip():
            out += ["Notes", "-----", *lines[k:]]  # a paragraph about the parameters as a whole
            break
        parts = re.split(r";\s+(?=(\*{0,2}[A-Za-z_]\w*):\s)", line)
        pieces, current = [], parts[0]
        for name, rest in zip(parts[1::2], parts[2::2], strict=True):
            if name.lstrip("*") in parameters:  # "a: …; b: …": b starts an item of its own
                pieces.append(current)
                current = rest
            else:
                current += "; " + rest
        pieces.append(current)
        for piece in pieces:
            match = is_item(piece)
            if match is None:  # a continuation written without indentation
                out.append("    " + piece)
                continue
            for name in re.split(r",\s*", match.group(1)):  # one entry per name: its own type
                out += [name] + (["    " + match.group(2)] if match.group(2) else [])
    return out


def rewrite(text: str, returns: str | None = None, parameters: set[str] | None = None) -> str:
    """The docstring ``text`` in the form griffe's numpy parser reads (see the module docstring);
    ``returns`` is the function's return annotation, ``parameters`` the names of its parameters."""
    text = _ROLE.sub(_role, text)
    lines = text.split("\n")
    out = list(lines)
    for title, body, end in reversed(_sections(lines)):
        if title in _ITEM_SECTIONS:
            out[body:end] = _items(lines[body:end], parameters or set())
        elif title == "returns" and returns:
            block = lines[body:end]
            first = next((line for line in block if line.strip()), "")
            prose = " " in first.strip() and " : " not in first and not first.startswith(" ")
            if prose:
                out[body:end] = [returns] + [("    " + line) if line.strip() else line for line in block]
    return "\n".join(out)


class SpcoDocstrings(griffe.Extension):
    """Rewrite every docstring before it is parsed (:func:`rewrite`)."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is None or obj.is_class:  # a class: once its __init__ is known
            return
        returns = getattr(obj, "returns", None)
        parameters = {p.name for p in getattr(obj, "parameters", ())}
        obj.docstring.value = rewrite(obj.docstring.value, None if returns is None else str(returns),
                                      parameters)

    def on_class_members(self, *, cls: griffe.Class, **kwargs: Any) -> None:
        if cls.docstring is not None:
            cls.docstring.value = rewrite(cls.docstring.value, None, {p.name for p in cls.parameters})
