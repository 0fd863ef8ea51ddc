"""`python -m langtraj.interdrive.reader FILE...`: print how the prompt reader reads free-text prompt files
(`figures.main`).

See docs/interdrive.md ('Reading a prompt').
"""

import sys

from langtraj.interdrive.reader.figures import main

sys.exit(main())
