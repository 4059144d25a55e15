"""Test helpers: fault injection around the emulators (see faults.py) and test worlds (worlds.py)."""
