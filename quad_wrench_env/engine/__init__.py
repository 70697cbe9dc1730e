"""The engine every env runs: N vehicles in one PyBullet world (:mod:`.fleet`), its own arithmetic
compiled (:mod:`.kernels`), the physics step composed from the components' kernels (:mod:`.compose`,
:mod:`.compiled`), the observation layout (:mod:`.observation`) and the per-vehicle noise (:mod:`.noise`)."""
