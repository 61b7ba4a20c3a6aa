"""Untrusted text (file names, joint names, cells of a file) made safe where it lands: one
printable line in a message or a comment of XML, YAML or Python (:func:`printable`), or the
inside of an XML comment (:func:`xml_comment_text`)."""

from __future__ import annotations

import unicodedata


def printable(text: str) -> str:
    """``text`` with every character that is not printable on one line (controls, line and
    paragraph separators, surrogates of undecodable file names, unassigned code points) as a
    ``\\xNN`` / ``\\uNNNN`` escape: safe in a comment of XML, YAML or Python."""
    out = []
    for ch in text:
        category = unicodedata.category(ch)
        if category[0] == "C" or category in ("Zl", "Zp"):
            code = ord(ch)
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")
        else:
            out.append(ch)
    return "".join(out)


def xml_comment_text(text: str) -> str:
    """``text`` fit for an XML comment: printable, no ``--``, not ending in ``-``."""
    safe = printable(text)
    while "--" in safe:
        safe = safe.replace("--", "- -")
    return safe + " " if safe.endswith("-") else safe
