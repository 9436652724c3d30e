"""Stone Soup's YAML for nmci's components (entry point ``stonesoup.serialise.yaml``).

Stone Soup writes any of its ``Base`` components as a mapping tagged ``!<module>.<class>`` and
reads back tags under ``!stonesoup.``; :func:`yaml_init` reads those under ``!nmci.`` the same way.
"""

from ruamel.yaml.constructor import ConstructorError
from stonesoup.serialise import get_class


def _from_yaml(constructor, tag_suffix, node):
    try:
        class_ = get_class(f"!nmci.{tag_suffix}")
    except (ImportError, AttributeError):
        raise ConstructorError("while constructing an nmci component", node.start_mark,
                               f"unable to import component 'nmci.{tag_suffix}'", node.start_mark)
    constructor.deep_construct = True
    properties = [data for data in constructor.construct_yaml_omap(node)][0]
    try:
        return class_(**properties)
    except Exception as e:
        raise ConstructorError("while constructing an nmci component", node.start_mark, str(e), node.start_mark)


def yaml_init(yaml) -> None:
    """Registers the reading of ``!nmci.`` tags on Stone Soup's ``YAML`` instance.

    Parameters
    ----------
    yaml : :class:`stonesoup.serialise.YAML`
        Stone Soup's YAML reader and writer (it calls this through its entry point).
    """
    yaml.constructor.add_multi_constructor("!nmci.", _from_yaml)
