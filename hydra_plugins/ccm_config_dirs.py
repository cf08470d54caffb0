"""Hydra search-path plugin: the user's config directories before ccm's own (issue #39).

Hydra puts ``--config-dir`` and ``hydra.searchpath`` entries *after* the primary config
directory, so a user's ``task/smoke.yaml`` would be listed but never used. ``ccm run`` names the
user's directories in the environment variable :data:`ccm.experiment.user_configs.DIRS_ENV`
for the duration of the run (its sweep workers inherit it); this plugin puts them ahead of the
primary directory, so an option of the same name shadows the package's. Without the variable
the plugin does nothing, for ccm and for any other Hydra app.
"""

from __future__ import annotations

from hydra.core.config_search_path import ConfigSearchPath, SearchPathQuery
from hydra.plugins.search_path_plugin import SearchPathPlugin

from ccm.experiment.user_configs import env_dirs


class CcmConfigDirs(SearchPathPlugin):
    """Prepend the directories of ``CCM_CONFIG_DIRS`` (first listed, first searched)."""

    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        for d in reversed(env_dirs()):
            search_path.prepend("ccm user configs", f"file://{d}", SearchPathQuery(provider="main"))
