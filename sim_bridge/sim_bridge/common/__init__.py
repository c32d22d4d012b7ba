"""
The bottom layer: what every other part of sim_bridge may use.

Below everything: paths to worlds, models, scenarios and examples, YAML loading, text
helpers, the run's errors, the run's environment variables, what validators say of a value.

Imports nothing of sim_bridge.
"""
