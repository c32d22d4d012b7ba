"""
Every command line of sim_bridge.

Every command line, one per verb of ``./lab`` (run, grade, check, live, video, demo,
autograder, record) and their console scripts (lab_run, lab_grade, lab_check, lab_video).

May import everything; nothing imports it but the packages sim_bridge.run and sim_bridge.grade:
``python -m sim_bridge.run|grade``, the one Python entry where ``./lab`` is not (Gradescope's
run_autograder, tests that start the runner or the grader as a process).
"""
