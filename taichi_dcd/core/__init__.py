"""The floor every other part stands on: the Taichi runtime (the only `ti.init`), kernel launch
and cache helpers, SIMD lanes, small geometry and rigid-body math, and the Model/State fields."""

