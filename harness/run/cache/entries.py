"""The bytes of a stage-cache entry: a payload sealed with a checksum **bound to its key**.

An entry stored at ``rel = "<stage>/<key[:2]>/<key>.<ext>"`` is sealed with

    tag = sha256(b"harness-stage-cache\\0" + rel + b"\\0" + payload)                (no cache key set)
    tag = HMAC-SHA256(secret, b"harness-stage-cache\\0" + rel + b"\\0" + payload)  (HARNESS_CACHE_KEY set)

so an entry copied (or renamed) under another key, stage or extension no longer verifies: its tag
was computed for its old name. Two layouts carry the tag:

* **envelope** (JSON and ``.npy`` payloads): ``magic + hex(tag) + b"\\n" + payload``, magic
  ``HCE2 `` (sha256) or ``HCM2 `` (HMAC);
* **signed PNG** (images that other code opens by path): the PNG with one private ancillary chunk
  ``haRn`` holding ``magic + hex(tag)`` just before ``IEND``, the tag taken over every byte before
  that chunk. Viewers ignore the chunk (ancillary, private), so the entry stays an ordinary PNG;
  a truncated image has no ``IEND`` and no chunk and fails verification like a torn envelope.

**What this detects and what it cannot** (docs/safety.md): any change of
an entry's bytes (a flipped bit, a truncation, a hand edit) and any entry moved to another name.
With a plain sha256 anyone who can write the cache can also recompute a tag, so a *deliberately*
re-sealed wrong value is accepted (the stages' schema checks in :mod:`harness.run.verify` still
refuse implausible values). With ``HARNESS_CACHE_KEY`` (a secret shared by the users and nodes of a
cache, never stored in it) a tag cannot be forged without the secret: entries written by anyone
else are discarded and recomputed. Entries of one mode read in the other are discarded too.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import struct
import zlib

_DOMAIN = b"harness-stage-cache\0"
SHA_MAGIC = b"HCE2 "
MAC_MAGIC = b"HCM2 "
_TAG_HEX = 64
HEADER = len(SHA_MAGIC) + _TAG_HEX + 1
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_IEND = b"\x00\x00\x00\x00IEND\xaeB`\x82"
_CHUNK = b"haRn"  # ancillary (h), private (a), reserved bit clear (R), safe to copy (n)
_CHUNK_BYTES = 4 + 4 + len(SHA_MAGIC) + _TAG_HEX + 4
KEY_ENV = "HARNESS_CACHE_KEY"


def cache_secret() -> bytes | None:
    """The MAC secret of the caches this process opens (``HARNESS_CACHE_KEY``), or None."""
    value = os.environ.get(KEY_ENV, "")
    return value.encode("utf-8") if value else None


class Sealer:
    """Seals and opens entries for one secret (None: plain sha256)."""

    def __init__(self, secret: bytes | None = None):
        self.secret = secret
        self.magic = MAC_MAGIC if secret else SHA_MAGIC

    def tag(self, rel: str, payload: bytes) -> bytes:
        head = _DOMAIN + rel.encode("utf-8") + b"\0"
        if self.secret:
            mac = hmac.new(self.secret, head, hashlib.sha256)
            mac.update(payload)
            return mac.hexdigest().encode()
        h = hashlib.sha256(head)
        h.update(payload)
        return h.hexdigest().encode()

    def _mode_problem(self, magic: bytes) -> str | None:
        if magic == self.magic:
            return None
        if magic == MAC_MAGIC:
            return f"sealed with a cache key, and {KEY_ENV} is not set here"
        if magic == SHA_MAGIC:
            return f"not sealed with this cache's key ({KEY_ENV}); written without it"
        return "no checksum header (truncated, or not written by this version of the cache)"

    def _check(self, rel: str, magic: bytes, tag: bytes, payload: bytes) -> str | None:
        problem = self._mode_problem(magic)
        if problem is None and not hmac.compare_digest(tag, self.tag(rel, payload)):
            problem = "checksum mismatch (changed or damaged after it was written, or copied from another key)"
        return problem

    # JSON / .npy payloads ---------------------------------------------------------------
    def envelope(self, rel: str, payload: bytes) -> bytes:
        return self.magic + self.tag(rel, payload) + b"\n" + payload

    def open_envelope(self, rel: str, data: bytes) -> tuple[bytes | None, str | None]:
        """(payload, None) when the entry verifies under ``rel``, else (None, what is wrong)."""
        if len(data) < HEADER or data[HEADER - 1:HEADER] != b"\n":
            return None, "no checksum header (truncated, or not written by this version of the cache)"
        payload = data[HEADER:]
        problem = self._check(rel, data[:len(SHA_MAGIC)], data[len(SHA_MAGIC):HEADER - 1], payload)
        return (None, problem) if problem else (payload, None)

    # PNG images ------------------------------------------------------------------------
    def sign_png(self, rel: str, png: bytes) -> bytes:
        if not (png.startswith(_PNG_SIGNATURE) and png.endswith(_IEND)):
            raise ValueError("not a complete PNG (signature ... IEND)")
        body = png[:-len(_IEND)]
        data = self.magic + self.tag(rel, body)
        chunk = struct.pack(">I", len(data)) + _CHUNK + data + struct.pack(">I", zlib.crc32(_CHUNK + data))
        return body + chunk + _IEND

    def open_png(self, rel: str, data: bytes) -> tuple[bytes | None, str | None]:
        """(the PNG as stored, None) when it verifies under ``rel``, else (None, what is wrong)."""
        if not data.startswith(_PNG_SIGNATURE):
            return None, "not a PNG image"
        if not data.endswith(_IEND) or len(data) < len(_PNG_SIGNATURE) + _CHUNK_BYTES + len(_IEND):
            return None, "PNG without its end (truncated)"
        at = len(data) - len(_IEND) - _CHUNK_BYTES
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        if kind != _CHUNK or length != len(SHA_MAGIC) + _TAG_HEX:
            return None, "PNG without the cache's checksum chunk (not written by this version of the cache)"
        sealed = data[at + 8:at + 8 + length]
        problem = self._check(rel, sealed[:len(SHA_MAGIC)], sealed[len(SHA_MAGIC):], data[:at])
        return (None, problem) if problem else (data, None)
