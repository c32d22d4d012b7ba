"""
The grader.

The grader: scenarios and criteria, grading a run, batches and classes, isolation of student
code, marks, HTML reports, Gradescope.

May import runner and below (not live, not commands).
"""
