"""Lets this folder's tests import the shared ``pppbot eval`` runner (``eval_runs``)."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
