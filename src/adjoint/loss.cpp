// The loss is header-only (inlined into both passes); this unit checks it compiles standalone.
#include "adjoint/loss.h"
