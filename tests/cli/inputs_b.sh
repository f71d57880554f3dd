# Part b of test_inputs.sh (sourced: CAVE, ROOT, a.prt and the expect_* helpers are set).
