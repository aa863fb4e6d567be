// Two MAVLink drones fly a long leg each at once (tests/operator/test_pause_mavlink.py):
// the operator pauses them mid-leg; on resume each goes on to its leg's original end.
package LongLegs

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Mission() {
	PAR_Up()
	PAR_Legs()
	PAR_Down()
}

func PAR_Up() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	Drone1.Arm()
	Drone1.Takeoff(2)
}

func SEQ_Up2() {
	Drone2.Arm()
	Drone2.Takeoff(2)
}

func PAR_Legs() {
	Drone1.FlyByX(20)
	Drone2.FlyByY(20)
}

func PAR_Down() {
	Drone1.Land()
	Drone2.Land()
}
