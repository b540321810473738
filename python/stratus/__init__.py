"""Stratus from Python (issue 32). The package itself (the native module) comes from the
PyO3 build; this file only makes `stratus.batch` importable on its own."""
