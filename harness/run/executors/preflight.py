"""Checks of where a run will work, done before anything is created (output folder, cluster):

* **the cache location**: an fsspec URL is opened (an unknown protocol, or ``s3://`` without
  ``s3fs``, is one line); a store that lives inside one process (``memory://``) is refused when
  the work runs in other processes — a local pool of 2+ workers or Ray — where every worker would
  write into its own empty store and the driver would find nothing (the whole run lost);
* **the Ray cluster address**: ``HOST:PORT`` (its GCS) or ``ray://HOST:PORT`` (its client server)
  must accept a TCP connection within :data:`CONNECT_TIMEOUT_S`; otherwise ``ray.init`` would
  retry for minutes. ``auto`` must name a running cluster of this machine (``RAY_ADDRESS`` or the
  address file Ray writes when a cluster starts).
"""

from __future__ import annotations

import os
import socket

from harness.core.errors import InputError

#: how long a Ray cluster address may take to accept a connection
CONNECT_TIMEOUT_S = 10.0
#: where Ray records the GCS address of the cluster started on this machine (``address="auto"``)
CURRENT_CLUSTER = "/tmp/ray/ray_current_cluster"


def preflight(spec, workers: int, cache: str | None, *, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Refuse (InputError) a cache location or Ray address this run cannot use; see the module text."""
    from harness.run.cache.stores import is_url

    if cache and is_url(cache) and not cache.startswith("file://"):
        from harness.core.paths import cache_dir
        from harness.run.cache.stores import FsspecStore

        store = FsspecStore(cache, cache_dir() / "mirror")
        if store.process_local and (spec.name == "ray" or workers > 1):
            where = "Ray tasks" if spec.name == "ray" else f"{workers} worker processes"
            raise InputError("--cache", f"{cache} lives in this process's memory; the {where} would each write "
                                        "into their own copy and the run would find none of it. Give a folder or "
                                        "a shared URL (s3://...), or run with --workers 1 --executor local")
    if spec.name == "ray" and spec.address:
        check_ray_address(spec.address, timeout)


def _host_port(text: str, default_port: int) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep:
        return text, default_port
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError("--address", f"{text!r}: the port must be a number 1..65535")
    return host.strip("[]"), int(port)


def check_ray_address(address: str, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """One TCP connection to the cluster's address (nothing is sent), within ``timeout`` seconds."""
    if address == "auto":
        if os.environ.get("RAY_ADDRESS"):
            return check_ray_address(os.environ["RAY_ADDRESS"], timeout)
        try:  # the GCS address Ray writes when a cluster starts on this machine (stale once it stops)
            with open(CURRENT_CLUSTER, encoding="utf-8") as f:
                known = f.readline(256).strip()
        except OSError:
            known = ""
        if not known:
            raise InputError("--address", "auto: no Ray cluster is running on this machine (start one with "
                                          "`ray start --head`, or give HOST:PORT)")
        return check_ray_address(known, timeout)
    text = address[len("ray://"):] if address.startswith("ray://") else address
    host, port = _host_port(text, 10001 if address.startswith("ray://") else 6379)
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except socket.timeout:
        raise InputError("--address", f"{address}: no answer within {timeout:g} s (is a Ray cluster running there?)") \
            from None
    except OSError as err:
        raise InputError("--address", f"{address}: cannot connect ({err.strerror or err}); is a Ray cluster "
                                      "running there?") from None
