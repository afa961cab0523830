"""Noisy kinematic multi-robot simulator and scenario runner for PRVO."""
