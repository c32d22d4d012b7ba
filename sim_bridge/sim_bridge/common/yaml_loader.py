"""
The YAML loader of the kit's own files (worlds, scenarios): safe, strict, YAML 1.2 numbers.

PyYAML implements YAML 1.1, where a float needs a dot and a signed exponent: ``1.0e+3`` is a
number but ``1e3`` and ``1.0e3`` are text. YAML 1.2 (and JSON, and every other YAML library a
user may know) reads all three as floats, so this loader does too, with YAML 1.2's core-schema
float pattern added to PyYAML's resolver. A key given twice in one mapping is an error, not a
silent override. :func:`read_text` reads such a file, bounded: a world or a scenario that is a
link to ``/dev/zero`` or a named pipe is refused, never read without end.
"""

import errno
import os
import re
import stat
from typing import Any

import yaml

# YAML 1.2 core schema floats (https://yaml.org/spec/1.2.2/#1032-tag-resolution), plus the
# YAML 1.1 forms PyYAML already reads (``1_000.5``, ``.5``, sexagesimal, .inf, .nan).
_FLOAT = re.compile(r"""^(?:
     [-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
    |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.VERBOSE)


class StrictLoader(getattr(yaml, 'CSafeLoader', yaml.SafeLoader)):
    """
    YAML's safe loader with YAML 1.2 floats; a key given twice in one mapping is an error.

    libyaml's parser where PyYAML has it (twice as fast), the pure-Python one otherwise.
    """

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f'duplicate key {key!r}', key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


#: The largest kit YAML file read (bytes): a lab's world or scenario is a few KiB.
FILE_LIMIT_BYTES = 1024 * 1024


StrictLoader.add_implicit_resolver('tag:yaml.org,2002:float', _FLOAT, list('-+0123456789.'))


def load_yaml(text: str) -> Any:
    """Return the data of the YAML document ``text``; yaml.YAMLError when it is not YAML."""
    return yaml.load(text, Loader=StrictLoader)


def read_text(path: str | os.PathLike, limit: int = FILE_LIMIT_BYTES) -> str:
    """
    Return the UTF-8 text of the file ``path``: a world or a scenario.

    OSError (with ``strerror`` saying why) for a file that cannot be read, is not a regular
    file or is larger than ``limit`` bytes; UnicodeDecodeError for one that is not UTF-8.
    """
    if not stat.S_ISREG(os.stat(path).st_mode):
        raise OSError(errno.EINVAL, 'not a regular file', os.fspath(path))
    with open(path, 'rb') as file:
        data = file.read(limit + 1)
    if len(data) > limit:
        raise OSError(errno.EFBIG, f'larger than {limit // 1024} KiB, too large for a kit file',
                      os.fspath(path))
    return data.decode('utf-8')
