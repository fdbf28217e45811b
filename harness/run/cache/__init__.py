"""The stage cache and what its keys are made of.

* :mod:`~harness.run.cache.stage_cache`: the content-addressed, verified cache (:class:`StageCache`)
  and the digests its keys are built from (:func:`digest_json`, :class:`FileDigests` ...);
* :mod:`~harness.run.cache.entries`: how an entry is sealed (checksum or HMAC bound to its key);
* :mod:`~harness.run.cache.stores`: where entries live (a folder, or an fsspec URL);
* :mod:`~harness.run.cache.versions`: the code digests that version each stage's results.
"""

from harness.run.cache.stage_cache import (
    CACHE_FORMAT,
    FileDigests,
    StageCache,
    canonical_json,
    digest_bytes,
    digest_json,
    digest_mask,
    is_url,
    open_store,
)

__all__ = ["CACHE_FORMAT", "FileDigests", "StageCache", "canonical_json", "digest_bytes", "digest_json",
           "digest_mask", "is_url", "open_store"]
