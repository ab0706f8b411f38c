"""RoboCasa's placeholder asset tree (``python scenes/robocasa/placeholder_tree DST`` with the RoboCasa venv's
interpreter; ``scenes.robocasa.placeholders`` starts it). Its modules import only the standard library, numpy, PyYAML
and RoboCasa: the generator is not part of the ``scenes`` package's code paths (our venv reads only ``VERSION``).

The tree is the wheel's own ``models/assets`` (layouts, styles, fixture registry, procedural cabinet XML) plus, for
every file those reference that the wheel does not ship: a box ``model.xml`` per fixture carrying the joints, sites
and regions its fixture class looks up (the sink and the blender open at the top: a floor and four walls around
their basin / jar region); one box object per (registry, category); flat one-colour textures; a one-box mesh for
any mesh file. Pitfalls handled (issue 25): every joint has its own body (two joints on one body and axis make the
mass matrix singular); a door sits outside its body's collider (inside, MuJoCo resets mjData to qpos0
with only mjWARN_BADQACC set); the tree is written writable (objects write temporary XML into their folders).

Modules: ``model`` (one fixture's MJCF box model, the nominal sizes), ``built_in`` (sink, microwave, oven,
dishwasher, stove, fridge), ``countertop`` (stand mixer, electric kettle, coffee machine, blender, toaster, toaster
oven, racks and bowls), ``fixtures`` (which builder makes which fixture kind), ``files`` (objects, textures, meshes
and the writer), ``write`` (the registry walk that writes the tree), ``__main__`` (the entry point).
"""

MARKER = "INDGEN_PLACEHOLDER_TREE"  # a file at the root naming what wrote the tree
# 5: the sink and the blender are hollow; the blender has anchor_site, power_button_main; 6: the stand mixer's
# head overhangs its front (OpenStandMixerHead), the kettle's lid button collides and springs back, the fridge has
# its drawer and an open shelf, the stand mixer's bowl is open; 7: the toaster oven's door is hinged higher and
# thinner (CloseToasterOvenDoor: a finger gets under its open free edge); 8: the kettle's switch is RoboCasa's
# lever, low on its side, hinged at its inner end and pressed down at its free end; 9: a graspable category's box
# is shrunk (all three sides alike) where RoboCasa's scale would make it wider than GRASPABLE_WIDTH
VERSION = 9
