"""
The keyboard teleop's logic, without rclpy or a terminal: keys in, velocities and text out.

The layout, the speed steps and the texts are those of ROS 2 Jazzy's teleop_twist_keyboard
(which is not on PyPI): a move key sets a direction, a speed key scales the speeds by 10 %,
any other key stops, Ctrl-C quits.
"""

from dataclasses import dataclass, field

#: What the teleop prints when it starts, and again after every 15 speed changes.
BANNER = """
This node takes keypresses from the keyboard and publishes them
as Twist/TwistStamped messages. It works best with a US keyboard layout.
---------------------------
Moving around:
   u    i    o
   j    k    l
   m    ,    .

For Holonomic mode (strafing), hold down the shift key:
---------------------------
   U    I    O
   J    K    L
   M    <    >

t : up (+z)
b : down (-z)

anything else : stop

q/z : increase/decrease max speeds by 10%
w/x : increase/decrease only linear speed by 10%
e/c : increase/decrease only angular speed by 10%

CTRL-C to quit
"""

#: key: (x, y, z, th) direction; linear.x/y/z = direction × speed, angular.z = th × turn.
MOVE_BINDINGS = {
    'i': (1, 0, 0, 0),
    'o': (1, 0, 0, -1),
    'j': (0, 0, 0, 1),
    'l': (0, 0, 0, -1),
    'u': (1, 0, 0, 1),
    ',': (-1, 0, 0, 0),
    '.': (-1, 0, 0, 1),
    'm': (-1, 0, 0, -1),
    'O': (1, -1, 0, 0),
    'I': (1, 0, 0, 0),
    'J': (0, 1, 0, 0),
    'L': (0, -1, 0, 0),
    'U': (1, 1, 0, 0),
    '<': (-1, 0, 0, 0),
    '>': (-1, -1, 0, 0),
    'M': (-1, 1, 0, 0),
    't': (0, 0, 1, 0),
    'b': (0, 0, -1, 0),
}

#: key: (factor of speed, factor of turn).
SPEED_BINDINGS = {
    'q': (1.1, 1.1),
    'z': (0.9, 0.9),
    'w': (1.1, 1.0),
    'x': (0.9, 1.0),
    'e': (1.0, 1.1),
    'c': (1.0, 0.9),
}

#: The key Ctrl-C sends when the terminal is in raw mode.
CTRL_C = '\x03'
#: The banner is printed again after this many speed changes, so it stays on screen.
BANNER_EVERY = 15


@dataclass
class TeleopKeys:
    """
    The state of a keyboard teleop: speed (m/s), turn (rad/s) and the last direction.

    :meth:`press` takes one key; :attr:`velocity` is then the command to publish, unless
    :attr:`done` is set.
    """

    speed: float = 0.5
    turn: float = 1.0
    direction: tuple[int, int, int, int] = (0, 0, 0, 0)
    done: bool = False
    speed_changes: int = field(default=0, repr=False)

    def press(self, key: str) -> list[str]:
        """Apply one key (a one-character string); return the lines to print."""
        if key in MOVE_BINDINGS:
            self.direction = MOVE_BINDINGS[key]
            return []
        if key in SPEED_BINDINGS:
            speed_factor, turn_factor = SPEED_BINDINGS[key]
            self.speed = float(self.speed * speed_factor)
            self.turn = float(self.turn * turn_factor)
            lines = [self.status()]
            if self.speed_changes == BANNER_EVERY - 1:
                lines.append(BANNER)
            self.speed_changes = (self.speed_changes + 1) % BANNER_EVERY
            return lines
        self.direction = (0, 0, 0, 0)
        self.done = key == CTRL_C
        return []

    @property
    def velocity(self) -> tuple[float, float, float, float]:
        """Return the command (linear x, y, z in m/s, angular z in rad/s), as floats."""
        x, y, z, th = self.direction
        return (float(x * self.speed), float(y * self.speed), float(z * self.speed),
                float(th * self.turn))

    def status(self) -> str:
        """Return the speeds line, as teleop_twist_keyboard prints it."""
        return f'currently:\tspeed {round(self.speed, 6)}\tturn {round(self.turn, 6)} '
