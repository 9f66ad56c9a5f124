"""Command-line interface (``hrtls ...``), built with typer and rich."""
