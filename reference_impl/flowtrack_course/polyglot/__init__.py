"""The polyglot stack: building and running C++, Java, Octave, Mathematica and block-diagram code.

One stack serves both users of other languages, which import it and never each other:

- the ports (:mod:`flowtrack_course.ports`: ``flowtrack ports`` and the vector files), the course's
  own C++/Java/MATLAB/Mathematica/Simulink-style programs checked against the Python reference;
- the language grader (:mod:`flowtrack_course.grading.languages`), which builds and runs students'
  answers in those languages inside the sandbox.

Layers, bottom up:

- :mod:`.vectors`: the shared vectors format (its one JSON dump), the ``CASE`` lines a port harness
  prints and their comparison;
- :mod:`.base`: a :class:`~.base.Toolchain` (requirements, the grader's recipe), the one
  :class:`~.base.ToolchainMissing`, the build cache of what is compiled from the course's own sources;
- one module per language, its toolchain and its ports: :mod:`.cpp` (Eigen, PCL), :mod:`.java`
  (plain arrays, EJML, OpenCV), :mod:`.octave`, :mod:`.mathics` (with the one Wolfram-language writer
  and reader), :mod:`.blocks` (bdsim; ported only); the grader's harness files are in ``files/``;
- :mod:`.toolchains`: the registry, the one ``LANGUAGES``;
- :mod:`.problems`: every problem, its reference, its cases (the ports' vectors and the grader's
  public and hidden cases) and its catalogued mistakes, each defined once.

The stack imports nothing of the grader or of the ports' command.
"""
