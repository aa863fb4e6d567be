// 100 drones, their homes 5 m apart in a line (the default): a grid take-off (drone i flies
// to row i/10, place i%10: rows 50 m apart, 5 m between neighbours), a relay, a
// synchronised sweep, and landing by rows.
package fleet100

import "fleet"

var Team [100]Quadcopter

func SEQ_Mission() {
	PAR_Grid()
	for _, d := range Team { // the relay: one after the other, 1 m up and back
		d.FlyByZ(1)
		d.FlyByZ(-1)
	}
	PAR_Sweep(20) // the sweep: all at once 20 m north, and back once all are there
	PAR_Sweep(-20)
	for row := range 10 {
		fleet.PAR_Land(Team[10*row : 10*row+10])
	}
}

func PAR_Grid() {
	for i, d := range Team {
		fleet.SEQ_Up(d, 3)
		d.FlyToXYZ(5*(i%10), -5*(i%10), 3)
	}
}

func PAR_Sweep(dx float64) { for _, d := range Team { d.FlyByX(dx) } }
