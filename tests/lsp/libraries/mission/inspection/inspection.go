// Package inspection: a library in the mission's own folder (tests/lsp/test_libraries.py).
package inspection

// SEQ_Look climbs height_m, looks, and comes back down.
func SEQ_Look(d Quadcopter, height_m float64) {
	d.FlyByZ(height_m)
	d.FlyByZ(-height_m)
}
