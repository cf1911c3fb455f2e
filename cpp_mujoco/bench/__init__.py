"""Speed and memory benchmarks: commands that measure, never imported by the library."""
