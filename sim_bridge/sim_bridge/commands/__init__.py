"""
Every command line of sim_bridge.

Every command line: run, grade, live, video, task videos, demo, autograder.

May import everything; nothing imports it (the packages sim_bridge.run, .grade and .bridge
keep the paths users type).
"""
