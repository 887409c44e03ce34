"""Units at the edges: everything inside is SI (m, s, bit, bit/s, dB); Mbit appears only in
files, tables and plots."""

BITS_PER_MBIT = 1e6
"""Bits in one Mbit (10^6, as the AADM controller and the paper count)."""
