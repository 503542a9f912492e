"""asv benchmark suite of cartan (``asv run --python=same``; see docs/benchmarks.md)."""
