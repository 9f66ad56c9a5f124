"""User-facing jobs built from the library: track to a folder, the demo, the papers' benchmark.

This layer sits above the pipeline, the simulator and the evaluation harness; the CLI and the
service call it, it never prints.
"""
