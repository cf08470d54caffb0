"""Controllers written as a user outside ccm writes them, for the plugin tests (issue #41)."""
