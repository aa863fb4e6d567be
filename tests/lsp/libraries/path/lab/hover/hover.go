// Package hover: a library found on EAMOS_PATH as "lab/hover" (tests/lsp/test_libraries.py).
package hover

// SEQ_Wait holds where it is for duration_s.
func SEQ_Wait(d Quadcopter, duration_s float64) {
	d.PauseFor(duration_s)
}
