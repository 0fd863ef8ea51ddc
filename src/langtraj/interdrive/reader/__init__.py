"""Read which behaviour kind (`Behaviour`) a typed prompt asks of which agent: "@7, hang a left" -> @7 turn_left.

The simulator steers an agent by the kind a prompt asks for, so a prompt in everyday words must be read without the
phrase tables (`prompts.user.recognize_prompt` finds only their own phrases). The reader is rule-based: regular
expressions over the lower-cased text, with each `@id` mention replaced by a placeholder. It favours precision over
recall: a negated prompt, two different kinds, or a subject or other agent it cannot tell give no kind (and a
reason), so that a prompt it cannot read steers by its text alone rather than by a wrong kind.
`python -m langtraj.interdrive.reader FILE...` prints how it reads free-text prompt files.

The package holds `rules.py` (verb forms and the regular-expression rule tables), `read.py` (normalisation,
matching, subject finding and `read_prompt`, one clause), `clauses.py` (`read_clauses`: a prompt cut into its
clauses and agents, each read), `timing.py` (timing words found, kept in `PromptReading.condition`), `when.py`
(those that say a start, read as its trigger: `interdrive.triggers`),
`alone.py` (a pair kind's words with no second agent, an overtake alone) and `figures.py` (reading figures and the
command line).

See docs/interdrive.md ('Reading a prompt').
"""

from langtraj.interdrive.reader.clauses import clauses, read_clauses
from langtraj.interdrive.reader.figures import ReadingFigures, file_figures, main, reading_figures
from langtraj.interdrive.reader.read import PromptReading, read_prompt

__all__ = [
    "PromptReading",
    "ReadingFigures",
    "clauses",
    "file_figures",
    "main",
    "read_clauses",
    "read_prompt",
    "reading_figures",
]
