"""bayesdrag: drag coefficient Cd(M) from radar-tracked trajectories, with honest uncertainty."""
__version__ = "0.1.0"
