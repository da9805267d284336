"""Controllers by name: a registry the core owns and does not fill itself.

``acc-gym evaluate NAME``, the leaderboard and :func:`acc_gym.evaluation.runner.load_controller`
resolve a controller's name here. The core registers nothing: names come from

* the ``acc_gym.controllers`` **entry-point group** of any installed distribution (this
  project's own built-ins -- ``acc``, ``idm``, ..., the shipped policy ``ppo-acc`` -- are
  entry points of the ``acc-gym`` distribution, defined in the ``acc_gym_agents``
  package); an entry point names a class or a factory that returns an object with
  ``predict(obs, deterministic=True)``;
* :func:`register_controller` for code that is not installed (a notebook, a test).

A third-party package puts its controller on the leaderboard by name with, in its
``pyproject.toml``::

    [project.entry-points."acc_gym.controllers"]
    my-acc = "my_package.controllers:MyACC"

Saved models given by path (a run directory of ``acc-gym train`` or its ``model.zip``)
are opened by the loaders of the ``acc_gym.controller_loaders`` group: each is called
with the path and returns a controller, or None when the path is not of its kind.

Resolution order: names given to :func:`register_controller` (in this process), then
entry points. Two distributions that register the same name are an error naming both,
not a silent choice.
"""

from __future__ import annotations

from importlib import metadata

GROUP = "acc_gym.controllers"
LOADER_GROUP = "acc_gym.controller_loaders"
CLI_GROUP = "acc_gym.cli"

_REGISTERED: dict[str, tuple[object, str]] = {}
_DESCRIPTIONS: dict[str, str] = {}  # given to register_controller
DESCRIPTION_WIDTH = 100  # [characters] a description longer than this is cut, with "..."


def register_controller(name: str, factory, *, origin: str | None = None, replace: bool = False,
                        description: str | None = None) -> None:
    """Make ``name`` resolve to ``factory()`` (a class or a callable returning a controller);
    ``description``: the line ``acc-gym controllers`` shows for it (default: the first
    sentence of the factory's docstring, :func:`describe_controller`)."""
    if not isinstance(name, str) or not name or ":" in name or name != name.strip():
        raise ValueError(f"a controller name must be a non-empty string without ':' or surrounding spaces, got "
                         f"{name!r}")
    if not callable(factory):
        raise TypeError(f"controller {name!r}: the factory must be callable, got {type(factory).__name__}")
    if name in _REGISTERED and not replace:
        raise ValueError(f"controller {name!r} is registered already ({_REGISTERED[name][1]}); pass replace=True")
    if description is not None and (not isinstance(description, str) or not description.strip()):
        raise ValueError(f"controller {name!r}: a description must be a non-empty string, got {description!r}")
    where = origin or f"register_controller ({getattr(factory, '__module__', '?')})"
    _REGISTERED[name] = (factory, where)
    if description is not None:
        _DESCRIPTIONS[name] = description.strip()
    else:
        _DESCRIPTIONS.pop(name, None)


def unregister_controller(name: str) -> None:
    """Forget a name given to :func:`register_controller` (entry points stay)."""
    if name not in _REGISTERED:
        raise ValueError(f"controller {name!r} was not registered with register_controller")
    del _REGISTERED[name]
    _DESCRIPTIONS.pop(name, None)


def _entry_points(group: str) -> dict[str, list[metadata.EntryPoint]]:
    found: dict[str, list[metadata.EntryPoint]] = {}
    for ep in metadata.entry_points(group=group):
        if not any(ep.value == other.value for other in found.get(ep.name, [])):  # the same one seen twice
            found.setdefault(ep.name, []).append(ep)
    return found


def _origin(ep: metadata.EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    who = f"{dist.name} {dist.version}" if dist is not None else "an installed distribution"
    return f"entry point {ep.value} ({who})"


def registered_controllers() -> dict[str, str]:
    """Every name that resolves, sorted, with where it comes from."""
    out = {name: " | ".join(_origin(ep) for ep in eps) for name, eps in _entry_points(GROUP).items()}
    out.update({name: origin for name, (_, origin) in _REGISTERED.items()})
    return dict(sorted(out.items()))


def first_sentence(doc: str | None, width: int = DESCRIPTION_WIDTH) -> str | None:
    """The first sentence of a docstring's first paragraph as plain text (reStructuredText's
    ``literals`` and :role:`targets` unwrapped, whitespace collapsed; a sentence ends at a
    full stop outside parentheses before a capital letter or the paragraph's end), cut to
    ``width`` characters; None for no docstring."""
    import re

    if not doc or not doc.strip():
        return None
    para = " ".join(doc.strip().split("\n\n", 1)[0].split())
    para = re.sub(r":[a-z]+:`~?([^`<]*?)(?:\s*<[^>]*>)?`", lambda m: m.group(1).rsplit(".", 1)[-1], para)
    para = para.replace("``", "")
    text, depth = para, 0
    for k, ch in enumerate(para):  # a sentence ends at . ! ? outside parentheses, before a capital or the end
        depth += (ch in "([") - (ch in ")]")
        if ch in ".!?" and depth <= 0 and (k + 1 == len(para) or (para[k + 1] == " " and k + 2 < len(para)
                                                                    and para[k + 2].isupper())):
            text = para[:k + 1]
            break
    return text if len(text) <= width else text[:width - 3].rstrip() + "..."


def describe_controller(name: str) -> str | None:
    """What the controller ``name`` is, in one line: the ``description`` given to
    :func:`register_controller`, else the factory's ``description`` attribute, else the first
    sentence of its docstring (:func:`first_sentence`); None when it has none. A name that
    does not resolve is None; one whose entry point does not load is the ``ValueError`` of
    :func:`controller_factory`."""
    if name in _DESCRIPTIONS:
        return _DESCRIPTIONS[name]
    factory = controller_factory(name)
    if factory is None:
        return None
    own = getattr(factory, "description", None)
    if isinstance(own, str) and own.strip():
        return " ".join(own.split())
    return first_sentence(getattr(factory, "__doc__", None))


def controller_factory(name: str):
    """The factory registered for ``name``, or None."""
    if name in _REGISTERED:
        return _REGISTERED[name][0]
    eps = _entry_points(GROUP).get(name)
    if not eps:
        return None
    if len(eps) > 1:
        raise ValueError(f"controller {name!r} is registered twice: " + "; ".join(_origin(ep) for ep in eps))
    try:
        return eps[0].load()
    except Exception as exc:  # noqa: BLE001  (an installed plugin that does not import)
        raise ValueError(f"controller {name!r} ({_origin(eps[0])}) does not load: {type(exc).__name__}: {exc}") \
            from None


def make_controller(name: str, **params):
    """A new controller of the registered ``name`` (None if no such name); ``params`` go to its
    factory (``acc``'s gains, ``idm``'s ``a`` and ``b``, ...): one it does not take is a
    ``ValueError`` naming it."""
    factory = controller_factory(name)
    if factory is None:
        return None
    if params:
        try:
            obj = factory(**params)
        except TypeError as exc:
            raise ValueError(f"controller {name!r} does not take the parameters {params!r} ({exc})") from None
    else:
        obj = factory()
    if not hasattr(obj, "predict"):
        raise ValueError(f"controller {name!r}: its factory returned {type(obj).__name__}, which has no "
                         f"predict(obs, deterministic=True)")
    return obj


def load_saved(path: str, **options):
    """A saved model at ``path`` through the installed loaders (None if none claims it).
    ``options`` (e.g. ``algo="sac"``) go to every loader, which must then accept them."""
    for name, eps in sorted(_entry_points(LOADER_GROUP).items()):
        for ep in eps:
            loader = ep.load()
            controller = loader(path, **options)
            if controller is not None:
                return controller
    return None


def cli_plugins() -> dict[str, object]:
    """Subcommands contributed to ``acc-gym`` (group ``acc_gym.cli``): name -> an object with
    ``add_parser(subparsers)`` and ``run(args, parser) -> int``. One that does not import
    (its extra is not installed) is left out."""
    out = {}
    for name, eps in sorted(_entry_points(CLI_GROUP).items()):
        try:
            out[name] = eps[0].load()
        except ImportError:
            continue
    return out
