"""Test plug-in: never finishes (and starts a child that would outlive it)."""
import subprocess, time
subprocess.Popen(["sleep", "613.25"])
time.sleep(600)
