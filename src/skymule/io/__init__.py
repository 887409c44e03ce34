"""Files at the edges: recorded traces, run folders, map and mission exports."""
