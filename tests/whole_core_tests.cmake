# Read by CTest after the discovered tests (TEST_INCLUDE_FILES). Each of these tests runs fits on
# every core for minutes; two of them side by side under `ctest -j2` took 409 s each, against
# 132 s and 178 s one after the other (docs/notes/2026-12-03-scale-fit-speed-and-suite-time.md),
# so each takes both of CTest's slots.
set_tests_properties(LdrFit.SaturatedLightsAreBoundsNotValues
                     LdrFit.LightsSeenOnlySaturatedTakeTheScaleTheAlbedoAgreesOn PROPERTIES PROCESSORS 2)
