// Event handler with Abandon(): when Drone1's battery runs low during the
// survey, Drone1 comes back home and the rest of the survey is abandoned on
// both drones (Drone2's running leg is cancelled, its remaining legs are
// skipped, as a Do interrupts its Body); the mission goes on with PAR_Down.
// With the default battery model the survey completes; with
// tests/virtual/fast_drain.toml (Drone1 drains 60 % a minute) it is abandoned.
package WheneverAbandon

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Mission() {
	PAR_Up()
	SEQ_Survey()
	PAR_Down()
}

func SEQ_Survey() {
	Whenever(Drone1.Battery() < 75, SEQ_Home)
	PAR_Legs()
}

func PAR_Up() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	Drone1.Arm()
	Drone1.Takeoff(3)
}

func SEQ_Up2() {
	Drone2.Arm()
	Drone2.Takeoff(2)
}

func PAR_Legs() {
	SEQ_Legs1()
	SEQ_Legs2()
}

func SEQ_Legs1() {
	Drone1.FlyByX(20)
	Drone1.FlyByY(10)
	Drone1.FlyByX(-20)
}

func SEQ_Legs2() {
	Drone2.FlyByY(-20)
	Drone2.FlyByX(20)
	Drone2.FlyByY(30)
}

func SEQ_Home() {
	Drone1.FlyToXYZ(0, 0, 3)
	Abandon()
}

func PAR_Down() {
	SEQ_Down1()
	SEQ_Down2()
}

func SEQ_Down1() {
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Down2() {
	Drone2.Land()
	Drone2.Disarm()
}
