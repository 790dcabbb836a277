"""Benchmark scenes and the side-by-side harness: our tracer vs POV-Ray 3.7, Cycles (bpy) and raw embreex.

``python -m bench --help``; results go to docs/benchmarks.md.
"""
