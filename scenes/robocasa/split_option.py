"""RoboCasa365's split and RoboCasa's object registries as the family's options (``--split``, ``--obj-registries``;
the API's ``split``, ``obj_registries``): chosen once per command (``Scene.configured``, at the command's edge), the flag
over ``INDGEN_ROBOCASA_SPLIT`` / ``INDGEN_ROBOCASA_OBJ_REGISTRIES`` over the defaults (``splits.choice``), and
read through ``split_choice`` by the family and its environment and certificate parts."""

from __future__ import annotations

from typing import ClassVar

from scenes.robocasa.splits import check, choice


class SplitOption:
    """The ``RoboCasa`` family's split and registries: the command's (``configured``) or the environment's."""

    scene_options: ClassVar[tuple[str, ...]] = ("split", "obj_registries")
    # the command's (``configured``); None: the environment's
    _choice: tuple[str, tuple[str, ...]] | None = None

    def check_options(self, given) -> None:
        """``split`` one of RoboCasa365's, ``obj_registries`` a comma list of RoboCasa's registries (one line)."""
        super().check_options(given)  # type: ignore[misc]
        check(given.get("split"), given.get("obj_registries"))

    def configured(self, given) -> SplitOption:
        """This family under ``--split`` / ``--obj-registries`` where given, else what it was configured with,
        else the environment's (``splits.choice``): one choice for the whole command."""
        import copy

        self.check_options(given)
        split, registries = given.get("split"), given.get("obj_registries")
        if self._choice is None:
            chosen = choice(split=split, registries=registries)
        else:
            regs = tuple(r.strip() for r in registries.split(",")) if registries else self._choice[1]
            chosen = (split or self._choice[0], regs)
        out = copy.copy(self)
        out._choice = chosen
        return out

    def split_choice(self) -> tuple[str, tuple[str, ...]]:
        """The command's split and registries (``configured``), else the environment's (``splits.choice``)."""
        return self._choice if self._choice is not None else choice()

    def options(self) -> dict[str, str]:
        """The choice as the plan's builder carries it to workers (``SceneLevels.options``)."""
        split, registries = self.split_choice()
        return {"split": split, "obj_registries": ",".join(registries)}
