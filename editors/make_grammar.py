"""Writes editors/vscode/syntaxes/vplus.tmLanguage.json, the TextMate grammar of V+ (.V2, .v2, .pg files), from
the keyword tables of :mod:`aioadept.vplus.keywords` (the V+ Language Reference Guide's index), so that the
grammar knows every V+ instruction and function, implemented by the emulator or not.

Every rule matches within one line (V+ has no construct that spans lines), so no line ends inside an open scope.
Scopes: ``comment.line.semicolon``, ``string.quoted.double``, ``constant.numeric.{decimal,hex,binary,octal,
double}`` (radix constants ``^H23FF``, ``^B1001``, ``^346``, ``^D20000000``: V+ Language User's Guide v17,
"Numeric Representation"), ``constant.character`` (``'A``), ``constant.language`` (TRUE, PI), ``keyword.control``
(IF, GOTO, CALL, ...), ``keyword.other.instruction`` (any other instruction, as the first word of a statement),
``keyword.operator``, ``support.function`` (a function followed by ``(``, or one that takes no parentheses),
``entity.name.function`` (the name on a ``.PROGRAM`` line, and ``.call`` for a CALL, EXECUTE or REACTE target),
``entity.name.label`` (a step label and a GOTO's target), ``variable.parameter`` (a ``.PROGRAM`` line's
parameters), ``keyword.other.directive`` (``.PROGRAM``, ``.END``, data sections). All with the suffix ``.vplus``.

Usage: ``python editors/make_grammar.py`` (tests/unit/test_editor_grammar.py holds the file to its output).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from aioadept.vplus import keywords

OUT = Path(__file__).resolve().parent / "vscode" / "syntaxes" / "vplus.tmLanguage.json"

CONTROL = ("IF THEN ELSE END WHILE DO UNTIL FOR TO STEP CASE OF VALUE ANY GOTO CALL CALLS CALLP RETURN RETURNE "
           "EXIT NEXT HALT STOP PAUSE EXECUTE REACT REACTE REACTI").split()
MODIFIERS = "ALWAYS MONITOR BY THEN DO TO STEP OF".split()
BARE_FUNCTIONS = "HERE #HERE RANDOM TASK NULL PI TIME".split()
B = r"(?<![\w.$#])"       # no part of a longer name before: rs.end is a name, not END
E = r"(?![\w.$#])"


def _words(words) -> str:
    return "|".join(re.escape(w) for w in sorted(set(words), key=lambda w: (-len(w), w)))


def grammar() -> dict:
    control = set(CONTROL)
    jumps = {"GOTO", "CALL", "EXECUTE", "REACT", "REACTE", "REACTI"}     # their own rules scope the target too
    instructions = (keywords.INSTRUCTIONS | {"GLOBAL", "LOCAL", "AUTO"}) - control
    functions = keywords.FUNCTIONS
    constants = {"TRUE", "FALSE", "ON", "OFF", "PI"}
    types = {"REAL", "DOUBLE", "LOC", "PRECISION", "STRING"}
    name = r"[A-Za-z][A-Za-z0-9._]*"
    return {
        "$schema": "https://raw.githubusercontent.com/martinring/tmlanguage/master/tmlanguage.json",
        "name": "V+", "scopeName": "source.vplus", "fileTypes": ["V2", "v2", "pg"],
        "patterns": [{"include": "#comment"}, {"include": "#program"}, {"include": "#directive"},
                     {"include": "#statement-start"}, {"include": "#label"}, {"include": "#expression"}],
        "repository": {
            "comment": {"match": r"(;).*$", "name": "comment.line.semicolon.vplus",
                        "captures": {"1": {"name": "punctuation.definition.comment.vplus"}}},
            "program": {
                "match": rf"(?i)^\s*(\.PROGRAM)\s+({name})\s*(?:(\()([^);]*)(\)))?",
                "captures": {"1": {"name": "keyword.other.directive.program.vplus"},
                             "2": {"name": "entity.name.function.vplus"},
                             "3": {"name": "punctuation.definition.parameters.begin.vplus"},
                             "4": {"patterns": [{"match": rf"[$#]?{name}", "name": "variable.parameter.vplus"}]},
                             "5": {"name": "punctuation.definition.parameters.end.vplus"}}},
            "directive": {"match": r"(?i)^\s*(\.(?:END|LOCATIONS|PRECISION\s*POINTS|REALS|DOUBLES|STRINGS))"
                                   + E, "captures": {"1": {"name": "keyword.other.directive.vplus"}}},
            # a statement's first word, after its label if any: an instruction (not a variable being assigned,
            # which a name that is also an instruction may be: speed = 5)
            "statement-start": {
                "match": rf"(?i)^\s*(?:(\d+)\s+)?(?:({_words(control - jumps)})|({_words(instructions)})){E}"
                         r"(?!\s*(?:=(?!=)|\[))",
                "captures": {"1": {"name": "entity.name.label.vplus"}, "2": {"name": "keyword.control.vplus"},
                             "3": {"name": "keyword.other.instruction.vplus"}}},
            "label": {"match": r"^\s*(\d+)(?=\s|$)", "captures": {"1": {"name": "entity.name.label.vplus"}}},
            "expression": {"patterns": [
                {"include": "#comment"}, {"include": "#string"}, {"include": "#goto"}, {"include": "#call"},
                {"include": "#execute"}, {"include": "#number"},
                {"match": rf"(?i){B}({_words(functions)})(?=\s*\()", "name": "support.function.vplus"},
                {"match": rf"(?i){B}({_words(constants)}){E}", "name": "constant.language.vplus"},
                {"match": rf"(?i){B}({_words(BARE_FUNCTIONS)}){E}", "name": "support.function.vplus"},
                {"match": rf"(?i){B}({_words(keywords.OPERATORS)}){E}", "name": "keyword.operator.word.vplus"},
                {"match": rf"(?i){B}({_words(MODIFIERS)}){E}", "name": "keyword.control.vplus"},
                {"match": rf"(?i){B}({_words(types)}){E}", "name": "storage.type.vplus"},
                {"match": rf"[$#]?{name}", "name": "variable.other.vplus"},
                {"match": r"==|<>|<=|>=|=<|=>|[-+*/<>=]", "name": "keyword.operator.vplus"}]},
            "string": {"match": r'"[^"]*("|$)', "name": "string.quoted.double.vplus"},
            "goto": {"match": rf"(?i){B}(GOTO)\s+(\d+)",
                     "captures": {"1": {"name": "keyword.control.vplus"}, "2": {"name": "entity.name.label.vplus"}}},
            "call": {"match": rf"(?i){B}(CALL|REACTE|REACTI|REACT)\s+({name})",
                     "captures": {"1": {"name": "keyword.control.vplus"},
                                  "2": {"name": "entity.name.function.call.vplus"}}},
            "execute": {"match": rf"(?i){B}(EXECUTE)(\s*/C)?\s+(?:([^,;\s]+)\s*,?\s+)?({name})(?=\s*(?:\(|;|$))",
                        "captures": {"1": {"name": "keyword.control.vplus"},
                                     "3": {"patterns": [{"include": "#expression"}]},
                                     "4": {"name": "entity.name.function.call.vplus"}}},
            # '^' right after an operand is the power operator (x^2), elsewhere it starts a radix constant
            "number": {"patterns": [
                {"match": r"(?<=[\w)\]\"'.])\s*\^", "name": "keyword.operator.vplus"},
                {"match": r"\^[Hh][0-9A-Fa-f]+", "name": "constant.numeric.hex.vplus"},
                {"match": r"\^[Bb][01]+", "name": "constant.numeric.binary.vplus"},
                {"match": r"\^[Dd]\d+", "name": "constant.numeric.double.vplus"},
                {"match": r"\^[0-7]+", "name": "constant.numeric.octal.vplus"},
                {"match": rf"{B}(?:\d+\.?\d*|\.\d+)(?:[Ee][+-]?\d+)?", "name": "constant.numeric.decimal.vplus"},
                {"match": r"'.", "name": "constant.character.vplus"}]},
        },
    }


def text() -> str:
    return json.dumps(grammar(), indent=1) + "\n"


if __name__ == "__main__":
    OUT.write_text(text())

