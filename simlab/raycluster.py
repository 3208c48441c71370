"""Connecting to Ray, shared by the dataset backends and the experiment executors.

Ray is an optional extra (``pip install "simlab[ray]"``), imported only here and only
when a Ray backend is asked for.
"""

from __future__ import annotations

from types import ModuleType

from simlab.errors import ConfigError


def connect_ray(address: str | None = None) -> tuple[ModuleType, bool]:
    """Import Ray and make sure a runtime is up; returns ``(ray, owns_runtime)``.

    With ``address`` (an existing cluster: ``"auto"``, ``"ray://head:10001"``...) it
    connects there; without, it reuses a runtime this process already initialized or
    starts a local one. ``owns_runtime`` is True when this call started or connected the
    runtime, so the caller shuts it down when done, and never one it did not start.
    """
    try:
        import ray
    except ModuleNotFoundError:
        raise ConfigError("the ray backend needs Ray", key="backend",
                          fix='pip install "simlab[ray]", or use --backend local') from None
    if address is not None:
        if ray.is_initialized():
            raise ConfigError(f"Ray is already initialized in this process; cannot connect "
                              f"to {address!r}", key="address", fix="omit --address to reuse it")
        ray.init(address=address)
        return ray, True
    if not ray.is_initialized():
        ray.init(include_dashboard=False)
        return ray, True
    return ray, False


def check_address(backend: str, address: str | None) -> None:
    """``--address`` only makes sense with the Ray backend."""
    if backend != "ray" and address is not None:
        raise ConfigError("--address applies to the ray backend only", key="address",
                          fix="add --backend ray or drop --address")
