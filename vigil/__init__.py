"""Vigil domain package: skeletons, taxonomy, features, decision policy, metrics, wire protocol.

Imports no web framework, database or robot code; backend, worker and robot_agent import it.
"""

__version__ = "0.1.0"
