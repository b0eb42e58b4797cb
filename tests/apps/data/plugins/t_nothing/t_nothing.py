"""Test plug-in: exits 0 without writing its output."""
import sys
sys.exit(0)
