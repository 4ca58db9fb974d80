"""The thesis reproduced: ``python -m reproduce`` regenerates every figure and table of chapters 2 and 3.

==============  ============================================================================================
``films``       the chapter-2 film runs, one resumable sweep (seeds per point: 5 by default, 10 in the report)
``chapter2``    Fig 2-2 to 2-6 and Table 2.1 from those boards
``chapter3``    Fig 3-8 to 3-13 (hill, depression, convergence, Ta film, k_exp)
``item``        what an item is (the thesis's words, our results, a verdict computed from them)
``__main__``    the command: runs the items and writes ``docs/reproduction.md``
==============  ============================================================================================
"""
