"""Orchestrator: scenarios, FMU build, the fmpy co-simulation master, Rerun traces, CLI."""
