"""Speed benchmarks, run as ``python -m benchmarks [name ...]``.

Each benchmark times kisscal against a reference measured in the same run (for example
OpenCV on the same images) and prints the ratio plus absolute throughput. Benchmarks are
not part of the test suite's pass/fail: the machines here are shared and noisy.
"""
