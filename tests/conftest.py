"""Test configuration: hypothesis runs derandomised under CI, so a landing never depends on
which examples a random seed happened to draw (run locally for fresh examples)."""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
