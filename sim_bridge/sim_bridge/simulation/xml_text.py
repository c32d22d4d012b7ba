"""
Reading the XML of Gazebo's files (SDF, model.config, URDF) as leniently as Gazebo does.

Gazebo reads XML with TinyXML2, which lets pass what strict XML refuses and what real files
hold: ``--`` inside a comment (Gazebo's own example worlds quote shell commands there), a
namespace prefix never declared (``<gz:policies>``), the ``<?xml ...?>`` declaration after a
licence comment. :func:`parse_xml` tries the standard library's strict parser first and, on
failure, lxml's recovering parser, keeping its tree only when every complaint is one of those
(:data:`TOLERATED`); a truncated or garbled file is still an error naming the line.
The result is a standard-library ``ElementTree.Element`` either way, comments dropped.
"""

from pathlib import Path
from xml.etree import ElementTree

#: libxml2's complaints about what TinyXML2 accepts (lxml.etree.ErrorTypes names).
TOLERATED = frozenset({'ERR_HYPHEN_IN_COMMENT', 'NS_ERR_UNDEFINED_NAMESPACE',
                       'ERR_RESERVED_XML_NAME', 'ERR_COMMENT_NOT_FINISHED',
                       'NS_ERR_QNAME', 'ERR_ATTRIBUTE_WITHOUT_VALUE',
                       'ERR_ATTRIBUTE_NOT_STARTED'})


class XmlError(ValueError):
    """A file that is not XML even by Gazebo's measure; the message names file and line."""


def parse_xml(text: str, path: Path) -> ElementTree.Element:
    """Return the root element of ``text`` (read from ``path``); XmlError when it is not XML."""
    try:
        return ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        strict_error = error
    from lxml import etree  # only for the files strict XML refuses
    parser = etree.XMLParser(recover=True, remove_comments=True, remove_pis=True,
                             resolve_entities=False, no_network=True)
    try:
        root = etree.fromstring(text.lstrip().encode('utf-8'), parser)
    except etree.XMLSyntaxError:
        root = None
    problems = [entry for entry in parser.error_log if entry.type_name not in TOLERATED]
    if root is None or problems:
        raise XmlError(f'{path}: invalid XML: {strict_error}') from None
    return _standard(root)


def _standard(element) -> ElementTree.Element:
    """Return an lxml element and its subtree as standard-library elements."""
    copy = ElementTree.Element(element.tag, dict(element.attrib))
    copy.text, copy.tail = element.text, element.tail
    copy.extend(_standard(child) for child in element)
    return copy
