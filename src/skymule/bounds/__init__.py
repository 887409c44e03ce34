"""Upper bounds on what any policy can download (LPs via HiGHS; see docs/bounds.md)."""
