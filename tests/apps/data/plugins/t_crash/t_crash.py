"""Test plug-in: prints a line on stderr, then dies of SIGSEGV."""
import os, signal, sys
print("about to crash on purpose", file=sys.stderr, flush=True)
os.kill(os.getpid(), signal.SIGSEGV)
