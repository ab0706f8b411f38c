"""``python scenes/robocasa/placeholder_tree DST`` (the RoboCasa venv's interpreter): write the tree at DST and
print its counts as one JSON line (``scenes.robocasa.placeholders`` reads it)."""

import json
import sys
from pathlib import Path

# run as a folder, Python puts the folder itself first on the path (its modules would import as top-level names,
# ``model``, ``files``...): its parent instead makes it the package ``placeholder_tree``
sys.path[0] = str(Path(__file__).resolve().parent.parent)

from placeholder_tree.write import write_tree  # noqa: E402

print(json.dumps(write_tree(Path(sys.argv[1]))))
