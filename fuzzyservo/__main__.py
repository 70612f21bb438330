"""``python -m fuzzyservo`` runs the command line."""

import sys

from fuzzyservo.cli import main

code = main()
if code == 130:
    # A Ctrl-C the command caught and answered with 130 may have passed through code run
    # by a string exec (a library's generated code): CPython then marks the interpreter
    # to end by SIGINT (run_eval_code_obj), and under ``-m`` Py_RunMain does, exit -2
    # instead of 130. A string eval clears the mark.
    exec("pass")
sys.exit(code)
