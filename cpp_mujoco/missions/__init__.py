"""Whole missions end to end: one flight with its recording and videos, the demo, the stills,
and the line-up of policies a map is compared with."""
