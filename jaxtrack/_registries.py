"""One name -> recipe table, the shape of the tracker, likelihood and manifold-kind registries
(``tracking.register_tracker``, ``likelihood.register_likelihood``,
``manifold.register_manifold_kind``): registration order kept, a name registered once unless
replaced, errors that list what is registered."""

from __future__ import annotations

from typing import Generic, TypeVar

Recipe = TypeVar("Recipe")


def check_name(what: str, name) -> None:
    """Raise ``ValueError`` unless ``name`` is a non-empty word (a command-line choice)."""
    if not name or not isinstance(name, str) or any(c.isspace() for c in name):
        raise ValueError(f"a {what}'s name must be a non-empty word, got {name!r}")


class Registry(Generic[Recipe]):
    """Recipes of one type by their ``name`` attribute.

    Args:
        what: the concept, singular ("tracker", "likelihood", "manifold kind").
        recipe_type: the class every registered recipe is an instance of.
        register_name: the public function that registers (named in type errors).
    """

    def __init__(self, what: str, recipe_type: type, register_name: str):
        self.what, self.recipe_type, self.register_name = what, recipe_type, register_name
        self._recipes: dict[str, Recipe] = {}

    def register(self, recipe: Recipe, *, replace: bool = False) -> Recipe:
        if not isinstance(recipe, self.recipe_type):
            raise TypeError(f"{self.register_name} takes a {self.recipe_type.__name__}, got {type(recipe).__name__}")
        name = recipe.name
        if name in self._recipes and not replace:
            raise ValueError(f"a {self.what} named {name!r} is already registered (pass replace=True to redefine it)")
        self._recipes[name] = recipe
        return recipe

    def get(self, name: str) -> Recipe:
        if name not in self._recipes:
            raise ValueError(f"unknown {self.what} {name!r}; registered {self.what}s: {', '.join(self._recipes)}")
        return self._recipes[name]

    def unregister(self, name: str) -> None:
        self.get(name)
        del self._recipes[name]

    def names(self) -> tuple[str, ...]:
        return tuple(self._recipes)

    def recipes(self) -> tuple[Recipe, ...]:
        return tuple(self._recipes.values())
