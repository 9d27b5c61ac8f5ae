# kernel.config (written for linux-source-6.1) made for 7.3, the judged kernel's tree
# (tests/system/run --judge): two options renamed since 6.1, same meaning.
# BASE_FULL became its inverse, BASE_SMALL (tinyconfig turns it on).
s/^CONFIG_BASE_FULL=y$/# CONFIG_BASE_SMALL is not set/
# PROC_SYSCTL became SYSCTL.
s/^CONFIG_PROC_SYSCTL=y$/CONFIG_SYSCTL=y/
