// Four drones as a group: they take off one after the other (a relay), fly a square each,
// all at once (the odd ones a longer one), and once every one of them is up, land in two halves.
package team_relay

import "fleet"

var Team [4]Quadcopter

func SEQ_Main() {
	fleet.SEQ_TakeOff(Team, 2)
	PAR_Squares()
	WaitUntil(All(Team.Z() > 1.5), SEQ_Land)
}

func PAR_Squares() {
	for i, d := range Team {
		d.FlyByX(1 + i%2)
		d.FlyByY(1)
		d.FlyByX(-1 - i%2)
		d.FlyByY(-1)
	}
}

func SEQ_Land() {
	for half := range 2 {
		fleet.PAR_Land(Team[2*half : 2*half+2])
	}
}
