"""MuJoCo 3-D backend (issue #42): the Panda with ccm's block tool in MuJoCo."""
