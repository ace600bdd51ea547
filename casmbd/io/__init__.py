"""Input/output: expression strings and scene files."""
