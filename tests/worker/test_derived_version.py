from worker.jobs.common import derived_version


def test_a_derived_version_keeps_the_parent_whole_and_names_the_job():
    parent = "rf-default-walking-20261202T130512-j2"
    assert derived_version(parent, "rt", 3) == "rf-default-walking-20261202T130512-rt3"
    # Re-thresholding a re-thresholded model does not pile suffixes up.
    assert derived_version("rf-default-walking-20261202T130512-rt3", "rt", 9) == (
        "rf-default-walking-20261202T130512-rt9"
    )


def test_a_long_parent_is_shortened_at_a_hyphen_within_the_limit():
    parent = "gbt-keypoints-urfd-without-fall-01-and-adl-07-20261202T130512-extra"
    name = derived_version(parent, "rt", 12345)
    assert len(name) <= 64 and name.endswith("-rt12345")
    assert parent.startswith(name.removesuffix("-rt12345") + "-")  # cut between words
