"""Sweep job directory names (issue #19): ``hydra.sweep.subdir`` is
``${ccm.job_dir:${hydra.job.override_dirname}}`` (configs/config.yaml).

Hydra names a job's directory after its overrides, so a ``/`` in an override value (``..``
included) put the job outside the sweep directory, and a long value made a name the file
system refuses. :func:`job_dir_name` keeps a safe name as it is (a resumed sweep finds its
finished jobs by name) and otherwise replaces the unsafe characters and cuts the name to
:data:`ccm.core.errors.NAME_MAX` bytes, ending it with a hash of the full overrides so two jobs
never share a directory. The resolver is registered when :mod:`ccm.cli` is imported: in the
launching process and in every launcher worker (they import the pickled task function).
"""

from __future__ import annotations

import hashlib
import re

from ccm.core.errors import NAME_MAX

RESOLVER = "ccm.job_dir"
#: path separators and control characters: never part of a job's directory name
_UNSAFE = re.compile(r"[/\\\x00-\x1f\x7f]")
_HASH = 10  # hex digits of the suffix


def job_dir_name(overrides: str) -> str:
    """One safe path component for a job whose ``override_dirname`` is ``overrides``."""
    safe = _UNSAFE.sub("_", overrides)
    if safe == overrides and len(overrides.encode()) <= NAME_MAX and overrides not in ("..", "."):
        return overrides
    digest = hashlib.sha256(overrides.encode()).hexdigest()[:_HASH]
    head = safe.encode()[: NAME_MAX - _HASH - 1].decode(errors="ignore")
    return f"{head}~{digest}"


def register() -> None:
    """Register the ``ccm.job_dir`` OmegaConf resolver (once per process)."""
    from omegaconf import OmegaConf

    if not OmegaConf.has_resolver(RESOLVER):
        OmegaConf.register_new_resolver(RESOLVER, job_dir_name)
