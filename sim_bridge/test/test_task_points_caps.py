"""
Tasks 1 and 3 graded on nodes that cap what they print as their authors chose.

The handout caps at 10 m; students cap at their TurtleBot3's 3.5 m, at a parameter of 5 m, at
12 m, not at all (inf), or print a word for no return. Each keeps its cap and earns both points
of its task in the shipped scenario; a node that prints a wrong number (the rightmost beam as
the range ahead, the regions' labels swapped) loses the second point with a one-line reason.
"""

import json
from pathlib import Path
import re

import pytest

from sim_bridge.commands import grade

WORKSPACE = Path(__file__).resolve().parents[2]

SCAN_AHEAD = """\
import math

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class ScanAhead(Node):
    def __init__(self):
        super().__init__('scan_ahead')
        self.max_range = self.declare_parameter('max_range', 5.0).value
        self.create_subscription(LaserScan, 'scan', self.callback, 10)

    def callback(self, msg):
        front = msg.ranges[len(msg.ranges) // 2]
{body}

def main():
    rclpy.init()
    rclpy.spin(ScanAhead())


if __name__ == '__main__':
    main()
"""
#: A student's callback body, after ``front`` (m) is read, by the student's name.
RANGE_AHEAD = {
    'tb3_cap': "        if front > 3.5:\n            front = 3.5  # my TurtleBot3's LDS\n"
               "        self.get_logger().info(f'Front: {front:.2f} m')\n",
    'param_cap': "        self.get_logger().info(f'Range ahead: {min(front, self.max_range)}')\n",
    'cap_12': "        print('distance ahead =', round(min(front, 12.0), 3), flush=True)\n",
    'no_cap': "        self.get_logger().info('Range ahead: ' + str(front))\n",
    'word': "        text = 'out of range' if math.isinf(front) else f'{front:.2f} m'\n"
            "        self.get_logger().info(f'Obstacle ahead: {text}')\n",
    'wrong_beam': "        self.get_logger().info(f'Range ahead: {min(msg.ranges[0], 10.0)}')\n",
}

SCAN_AROUND = """\
import math

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

NAMES = {names}


class ScanAround(Node):
    def __init__(self):
        super().__init__('scan_around')
        self.create_subscription(LaserScan, 'scan', self.callback, 10)

    def callback(self, msg):
        for index, name in enumerate(NAMES):
            value = min(msg.ranges[index * 7:(index + 1) * 7 + (index == 4)])
{body}

def main():
    rclpy.init()
    rclpy.spin(ScanAround())


if __name__ == '__main__':
    main()
"""
RIGHT_TO_LEFT = ['right', 'front-right', 'front', 'front-left', 'left']
#: A student's regions: their labels in the order of the beams, and what prints ``value``.
REGIONS = {
    'tb3_cap': (RIGHT_TO_LEFT, "            self.get_logger().info(f'Range {name}: "
                               "{min(value, 3.5):.2f}')\n"),
    'word': (RIGHT_TO_LEFT, "            self.get_logger().info(f'{name}: ' + ('no obstacle' if "
                            "math.isinf(value) else f'{value:.2f}'))\n"),
    'wrong_beam': (RIGHT_TO_LEFT[::-1], "            self.get_logger().info(f'{name}: "
                                        "{min(value, 10.0):.2f}')\n"),
}
RIGHT_POINT = 'printed right (capped as the node caps)'


@pytest.fixture(scope='module')
def marks(tmp_path_factory):
    """Grade every student's nodes in the shipped scan_ahead and scan_around; their tasks."""
    root = tmp_path_factory.mktemp('caps')
    scenarios = root / 'scenarios'
    scenarios.mkdir()
    for name in ('scan_ahead', 'scan_around'):
        text = (WORKSPACE / 'scenarios' / f'{name}.yaml').read_text()
        (scenarios / f'{name}.yaml').write_text(text)
    for student, body in RANGE_AHEAD.items():
        folder = root / 'submissions' / student
        folder.mkdir(parents=True)
        (folder / 'scan_ahead.py').write_text(SCAN_AHEAD.format(body=body))
    for student, (names, body) in REGIONS.items():
        (root / 'submissions' / student / 'scan_around.py').write_text(
            SCAN_AROUND.format(names=names, body=body))
    out = root / 'out'
    grade.main([str(scenarios), '--submissions', str(root / 'submissions'), '--out', str(out),
                '--no-record', '--no-plot', '--quiet'])
    return {student: {task['task']: task for task in json.loads(
        (out / 'students' / student / 'report.json').read_text())['marks']['tasks']}
        for student in RANGE_AHEAD}


def lost(task):
    return {point['point']: point['why'] for point in task['points'] if point['lost']}


@pytest.mark.parametrize('student', ['tb3_cap', 'param_cap', 'cap_12', 'no_cap', 'word'])
def test_a_range_ahead_capped_as_its_author_chose_earns_both_points(marks, student):
    assert marks[student]['1']['marks'] == 2.0, lost(marks[student]['1'])


@pytest.mark.parametrize('student', ['tb3_cap', 'word'])
def test_regions_capped_as_their_author_chose_earn_both_points(marks, student):
    assert marks[student]['3']['marks'] == 2.0, lost(marks[student]['3'])


@pytest.mark.parametrize('task, what', [('1', 'the range ahead'),
                                        ('3', 'the five region minima')])
def test_a_wrong_number_loses_the_point_with_a_one_line_reason(marks, task, what):
    reasons = lost(marks['wrong_beam'][task])
    # Another beam's range (or a region under another's name) is not the value asked for: no
    # scan has its line either.
    assert list(reasons) == [f'prints {what} for each scan', f'{what} {RIGHT_POINT}']
    why = reasons[f'{what} {RIGHT_POINT}']
    assert '\n' not in why
    assert re.search(r' printed \S+ at t=[\d.]+ s, truth [\d.]+ m: ', why), why
