"""The schema revisions, oldest first: ``0001_initial`` (v1), ``0002_session_temperature`` (v2)."""
