"""The OctoMap library's Python bindings (octomap-python), an optional dependency."""

from __future__ import annotations

from types import ModuleType

INSTALL_HINT = "OctoMap bindings missing: pip install 'ehm[octomap]'"


def octomap_module() -> ModuleType:
    """The `octomap` module; ImportError with the install hint where it is missing."""
    try:
        import octomap
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error
    return octomap
