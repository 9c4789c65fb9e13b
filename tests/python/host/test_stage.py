"""base.stage: the steps a computation names reach the sink of the block they run in, and
nothing without one."""

from playscope.base.stage import stage, stage_sink


def test_steps_reach_the_blocks_sink_and_nothing_outside_it():
    seen = []
    stage("before")  # no sink: a no-op
    with stage_sink(seen.append):
        stage("onsets")
        with stage_sink(lambda n: seen.append("inner " + n)):
            stage("pose")
        stage("families")
    stage("after")
    assert seen == ["onsets", "inner pose", "families"]


def test_calibrate_names_its_steps():
    from playscope.fit.calibration import calibrate

    from .synth import angle_session

    seen = []
    with stage_sink(seen.append):
        calibrate(angle_session())
    assert seen[0] == "c per frame" and "the model family" in seen
