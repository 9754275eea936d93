"""Benchmarks of envkit and what they share (common.py). Run them through their .sh wrappers, or as
`PYTHONPATH=scripts python3 -m bench.NAME` from the repository root."""
