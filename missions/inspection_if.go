// Inspection with a battery check (If/Else).
// Drone1 inspects a 4 m x 4 m roof outline at 3 m if its battery is above
// 50 %, otherwise only the first 2 m; Drone2 films from 5 m in both cases,
// but only follows the full outline when Drone1 flies it too.
// Frame: X north, Y east, Z up, metres from each drone's take-off point.
package InspectionIf

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Inspection() {
	PAR_Arm()
	PAR_Takeoff()
	Drone2.TurnOnCamera()
	If(Drone1.Battery() > 50, PAR_FullInspection, SEQ_ShortInspection)
	PAR_Home()
	PAR_Land()
}

func PAR_Arm() {
	Drone1.Arm()
	Drone2.Arm()
}

func PAR_Takeoff() {
	Drone1.Takeoff(3)
	Drone2.Takeoff(5)
}

func PAR_FullInspection() {
	SEQ_Outline1()
	SEQ_Outline2()
}

func SEQ_Outline1() {
	Drone1.FlyToXYZ(4, 0, 3)
	Drone1.FlyToXYZ(4, 4, 3)
	Drone1.FlyToXYZ(0, 4, 3)
}

func SEQ_Outline2() {
	Drone2.FlyToXYZ(4, 0, 5)
	Drone2.FlyToXYZ(4, 4, 5)
	Drone2.FlyToXYZ(0, 4, 5)
}

func SEQ_ShortInspection() {
	Drone1.FlyToXYZ(2, 0, 3)
	Drone1.PauseFor(3)
}

func PAR_Home() {
	Drone1.FlyToXYZ(0, 0, 3)
	Drone2.FlyToXYZ(0, 0, 5)
}

func PAR_Land() {
	SEQ_Land1()
	SEQ_Land2()
}

func SEQ_Land1() {
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Land2() {
	Drone2.Land()
	Drone2.Disarm()
}
