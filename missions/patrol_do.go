// Patrol with interruptions (DoUntil, DoWhile).
// DoUntil: Drone1 creeps north 2 m at a time; the moment it is more than
// 5 m north, the running move is cancelled (the drone holds position), the
// remaining moves are skipped and the Exit block runs.
// DoWhile: it then patrols east-west while its battery stays above 99 %
// (on the simulator it drains 1.5 % per minute in the air, so this runs out
// after about 40 s of flight); when the battery drops below, the patrol is
// cancelled and the Exit block flies it home and lands it. If the patrol
// ends first, it flies home and lands by itself and the Exit is skipped.
package PatrolDo

var Drone1 Quadcopter

func SEQ_Patrol() {
	Drone1.Arm()
	Drone1.Takeoff(3)
	DoUntil(Drone1.X() > 5, SEQ_Creep, SEQ_Hold)
	DoWhile(Drone1.Battery() > 99, SEQ_Beat, SEQ_LowBattery)
	Drone1.Disarm()
}

func SEQ_Creep() {
	Drone1.FlyByX(2)
	Drone1.FlyByX(2)
	Drone1.FlyByX(2)
	Drone1.FlyByX(2)
}

func SEQ_Hold() {
	Drone1.PauseFor(2)
}

func SEQ_Beat() {
	RepeatFor(5, SEQ_BackAndForth)
	Drone1.FlyToXYZ(0, 0, 3)
	Drone1.Land()
}

func SEQ_BackAndForth() {
	Drone1.FlyByY(6)
	Drone1.FlyByY(-6)
}

func SEQ_LowBattery() {
	Drone1.FlyToXYZ(0, 0, 3)
	Drone1.Land()
}
